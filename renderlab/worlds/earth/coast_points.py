r"""Coastline points for the geometric coastline-navigation study: GSHHG vertices, thinned, indexed.

The paper (Straub & Christian, Fig. 2b) matches "identified coastline points" inside the camera
footprint to a georeferenced database. Here the database is the real full-resolution GSHHG coastline
(:func:`renderlab.worlds.earth.gshhg.load_gshhg`, seams along the antimeridian and the south pole removed),
placed on the WGS-84 ellipsoid at zero height and thinned to at most one point per cube of side
``spacing_m`` (first vertex in file order wins, so the result is deterministic). A ``cKDTree`` over the
ECEF points answers "which points lie near this sub-satellite point" in microseconds.

The geometric study treats these points as exact (no map error): it is the paper's idealised mode.
:func:`points_in_view` finds the points a nadir camera with a square field of view sees (inside the image, facing
the camera) and :func:`spread_pick` keeps one per cell of a g×g image grid, so picked points spread over the image.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass

import numpy as np

from renderlab.worlds.earth import wgs84
from renderlab.worlds.earth.gshhg import load_gshhg

_LOCK = threading.Lock()
_CACHE: dict[float, "CoastlinePoints"] = {}

__all__ = ["CoastlinePoints", "coastline_points", "view_query_radius_m", "points_in_view", "spread_pick"]


@dataclass
class CoastlinePoints:
    """Thinned coastline database: ECEF points (n, 3) in metres, their outward ellipsoid normals and a KD-tree."""

    ecef_m: np.ndarray
    normal: np.ndarray
    tree: object  # scipy.spatial.cKDTree over ecef_m
    spacing_m: float


def _thin(xyz: np.ndarray, spacing_m: float) -> np.ndarray:
    """Indices of the first point in each cube of side spacing_m (sorted, deterministic)."""
    key = np.floor(xyz / spacing_m).astype(np.int64) + (1 << 20)
    flat = (key[:, 0] << 42) | (key[:, 1] << 21) | key[:, 2]
    _, first = np.unique(flat, return_index=True)
    return np.sort(first)


def coastline_points(spacing_m: float = 2000.0) -> CoastlinePoints:
    """The process-wide thinned GSHHG coastline (first call ≈10 s: GSHHG load, thinning, KD-tree)."""
    spacing_m = float(spacing_m)
    with _LOCK:
        if spacing_m not in _CACHE:
            import shapely
            from scipy.spatial import cKDTree

            lonlat = shapely.get_coordinates(load_gshhg().coast)
            xyz = wgs84.geodetic_to_ecef(np.radians(lonlat[:, 1]), np.radians(lonlat[:, 0]))
            xyz = xyz[_thin(xyz, spacing_m)]
            n = xyz / np.array([wgs84.A**2, wgs84.A**2, wgs84.B**2])
            n /= np.linalg.norm(n, axis=1, keepdims=True)
            _CACHE[spacing_m] = CoastlinePoints(xyz, n, cKDTree(xyz), spacing_m)
        return _CACHE[spacing_m]


def view_query_radius_m(radius_m: float, altitude_m: float, fov_rad: float) -> float:
    """Chord (m) from the sub-satellite point that holds a square nadir footprint on a sphere of radius ``radius_m``
    (Earth central angle of the FOV's corner ray), widened by 10 % and 30 km: the KD-tree query radius."""
    a_d = math.atan(math.sqrt(2.0) * math.tan(0.5 * fov_rad))
    lam = math.asin(min(1.0, (radius_m + altitude_m) / radius_m * math.sin(a_d))) - a_d
    return 2.0 * radius_m * math.sin(0.5 * lam) * 1.1 + 30e3


def points_in_view(db: CoastlinePoints, r_eci: np.ndarray, R_ecef_from_eci: np.ndarray, T_cam_from_eci: np.ndarray,
                   tan_half: float, radius_m: float, query_r: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Database points seen by the camera at ``r_eci``: inside the square image (|u|, |w| ≤ ``tan_half``), in front
    of it and facing it → ECI points (m, 3) and their image-plane tangents u, w (m,)."""
    r_ecef = R_ecef_from_eci @ r_eci
    sub = r_ecef / np.linalg.norm(r_ecef) * radius_m
    idx = np.asarray(db.tree.query_ball_point(sub, query_r), dtype=np.int64)
    if not idx.size:
        return np.zeros((0, 3)), np.zeros(0), np.zeros(0)
    p_ecef = db.ecef_m[idx]
    facing = np.einsum("ij,ij->i", db.normal[idx], r_ecef - p_ecef) > 0
    p_eci = (p_ecef @ R_ecef_from_eci)                               # Rᵀ p
    pc = (p_eci - r_eci) @ T_cam_from_eci.T
    u, w = pc[:, 0] / pc[:, 2], pc[:, 1] / pc[:, 2]
    inside = facing & (pc[:, 2] > 0) & (np.abs(u) <= tan_half) & (np.abs(w) <= tan_half)
    return p_eci[inside], u[inside], w[inside]


def spread_pick(u: np.ndarray, w: np.ndarray, tan_half: float, g: int) -> np.ndarray:
    """Indices of the points nearest the centre of each occupied cell of a g×g grid over the image (by cell)."""
    cu = np.clip(((u / tan_half + 1.0) * 0.5 * g).astype(int), 0, g - 1)
    cw = np.clip(((w / tan_half + 1.0) * 0.5 * g).astype(int), 0, g - 1)
    cell = cw * g + cu
    centre_u = ((cu + 0.5) / g * 2.0 - 1.0) * tan_half
    centre_w = ((cw + 0.5) / g * 2.0 - 1.0) * tan_half
    d2 = (u - centre_u) ** 2 + (w - centre_w) ** 2
    order = np.lexsort((d2, cell))                                   # by cell, then distance
    return order[np.r_[True, cell[order][1:] != cell[order][:-1]]]
