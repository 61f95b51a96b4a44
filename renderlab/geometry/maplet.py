"""Landmark maplets: the small DEM + relative-albedo tiles a stereophotoclinometry map uplinks.

A maplet is a square grid of ``n × n`` points (``n`` odd) spaced ``spacing_m`` apart in its own
frame M, whose origin is the landmark centre (a body-frame point) and whose +z axis is the local
"up" (out of the surface). Grid point (row j, column i) sits at

    x_i = (i − (n−1)/2)·s,   y_j = (j − (n−1)/2)·s,   z = heights_m[j, i]

in M, i.e. ``p_body = center_m + R_body_from_maplet @ [x_i, y_j, z]``. Columns of
``R_body_from_maplet`` are M's x (increasing column i), y (increasing row j) and z (up) axes in
the body frame; the frame is right-handed (det = +1). ``albedo`` is the relative albedo of each
grid point (mean ≈ 1). The landmark's truth pixel is the projection of ``center_m``.

Pure numpy: shared by the truth side (EV5 world, catalog files) and the estimators (Retina, SPC).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Maplet:
    """One landmark's maplet (see the module docstring for the geometry).

    Attributes
    ----------
    landmark_id : int
        Catalog id (≥ 0).
    center_m : numpy.ndarray
        (3,) landmark centre in the body frame, m.
    R_body_from_maplet : numpy.ndarray
        (3, 3) rotation, columns = maplet x, y, z axes in the body frame.
    spacing_m : float
        Grid spacing, m.
    heights_m : numpy.ndarray
        (n, n) heights along maplet +z, m; row j, column i.
    albedo : numpy.ndarray
        (n, n) relative albedo.
    """

    landmark_id: int
    center_m: np.ndarray
    R_body_from_maplet: np.ndarray
    spacing_m: float
    heights_m: np.ndarray
    albedo: np.ndarray

    def __post_init__(self):
        h = np.asarray(self.heights_m)
        if h.ndim != 2 or h.shape[0] != h.shape[1] or h.shape[0] % 2 == 0 or h.shape[0] < 3:
            raise ValueError(f"maplet {self.landmark_id}: heights must be an odd n×n grid (n ≥ 3), got {h.shape}")
        if np.shape(self.albedo) != h.shape:
            raise ValueError(f"maplet {self.landmark_id}: albedo shape {np.shape(self.albedo)} != heights {h.shape}")
        R = np.asarray(self.R_body_from_maplet, float)
        if R.shape != (3, 3) or not np.allclose(R.T @ R, np.eye(3), atol=1e-9) or np.linalg.det(R) < 0:
            raise ValueError(f"maplet {self.landmark_id}: R_body_from_maplet must be a proper rotation")
        if not (self.spacing_m > 0 and np.isfinite(self.spacing_m)):
            raise ValueError(f"maplet {self.landmark_id}: spacing_m must be positive, got {self.spacing_m}")
        if not (np.all(np.isfinite(h)) and np.all(np.isfinite(self.albedo))):
            raise ValueError(f"maplet {self.landmark_id}: heights and albedo must be finite")

    @property
    def n(self) -> int:
        """Grid points per side (odd)."""
        return int(np.shape(self.heights_m)[0])

    @property
    def half_width_m(self) -> float:
        """Distance from the centre to the outermost grid column, m."""
        return (self.n - 1) / 2 * self.spacing_m

    def grid_xy(self) -> tuple[np.ndarray, np.ndarray]:
        """Maplet-frame x (n,) of the columns and y (n,) of the rows, m."""
        t = (np.arange(self.n) - (self.n - 1) / 2) * self.spacing_m
        return t, t.copy()

    def points_maplet(self) -> np.ndarray:
        """(n, n, 3) grid points in the maplet frame, m."""
        x, y = self.grid_xy()
        X, Y = np.meshgrid(x, y)
        return np.stack([X, Y, np.asarray(self.heights_m, float)], axis=-1)

    def to_body(self, p_maplet: np.ndarray) -> np.ndarray:
        """Maplet-frame points (..., 3) → body frame."""
        return np.asarray(p_maplet, float) @ np.asarray(self.R_body_from_maplet, float).T + np.asarray(self.center_m, float)

    def points_body(self) -> np.ndarray:
        """(n, n, 3) grid points in the body frame, m."""
        return self.to_body(self.points_maplet())

    def height_at(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Bilinear height at maplet-frame (x, y); NaN outside the grid."""
        x = np.asarray(x, float)
        y = np.asarray(y, float)
        u = x / self.spacing_m + (self.n - 1) / 2
        v = y / self.spacing_m + (self.n - 1) / 2
        inside = (u >= 0) & (u <= self.n - 1) & (v >= 0) & (v <= self.n - 1)
        i0 = np.clip(np.floor(u).astype(int), 0, self.n - 2)
        j0 = np.clip(np.floor(v).astype(int), 0, self.n - 2)
        fu, fv = np.clip(u - i0, 0, 1), np.clip(v - j0, 0, 1)
        h = np.asarray(self.heights_m, float)
        out = ((1 - fu) * (1 - fv) * h[j0, i0] + fu * (1 - fv) * h[j0, i0 + 1]
               + (1 - fu) * fv * h[j0 + 1, i0] + fu * fv * h[j0 + 1, i0 + 1])
        return np.where(inside, out, np.nan)
