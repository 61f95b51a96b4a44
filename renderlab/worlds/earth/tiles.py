r"""Local tangent tiles: the ground (and cloud layer) of one Earth frame as triangle meshes in ENU metres.

Why: Mitsuba traces in float32; Earth-centred coordinates (≈ 6.4e6 m) would move secondary rays by
hundreds of metres. Each frame is rendered in the East-North-Up frame of the point where its boresight
meets the ellipsoid: ``p_ecef = R_ecef_from_render @ p_render + origin_ecef``.

The ground mesh is a G×G grid of image rays (the image widened by a margin) intersected with the WGS-84
ellipsoid, so its vertices lie exactly on the ellipsoid (chord sag d²/8R ≈ 2 m for 9 km cells). Its albedo
texture is a raster in the tile's (east, north) plane: every facet is planar, so (e, n) is linear on it and
the texture coordinate of any hit point is exact. The raster is GSHHG land coverage (polygons filled with
``antialias``² sub-cells per cell, i.e. the area fraction of land in the cell) at ≤ GSD/``texture_oversample``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from renderlab.errors import UserError
from renderlab.worlds.earth import footprint, wgs84


@dataclass(frozen=True)
class TileFrame:
    """The ENU render frame of one tile."""

    origin_ecef_m: np.ndarray
    R_ecef_from_render: np.ndarray
    lat_rad: float
    lon_rad: float

    @classmethod
    def at_boresight(cls, pos_ecef: np.ndarray, R_ecef_from_cam: np.ndarray) -> "TileFrame":
        t = wgs84.ray_ellipsoid(pos_ecef, R_ecef_from_cam[:, 2])
        if not np.isfinite(t):
            raise UserError("trajectory: the camera boresight misses the Earth (nadir pointing expected)")
        o = pos_ecef + t * R_ecef_from_cam[:, 2]
        lat, lon, _ = wgs84.ecef_to_geodetic(o)
        return cls(o, wgs84.R_ecef_from_enu(lat, lon), float(lat), float(lon))

    def to_render(self, p_ecef: np.ndarray) -> np.ndarray:
        return (np.asarray(p_ecef, float) - self.origin_ecef_m) @ self.R_ecef_from_render

    def to_ecef(self, p_render: np.ndarray) -> np.ndarray:
        return np.asarray(p_render, float) @ self.R_ecef_from_render.T + self.origin_ecef_m

    def to_dict(self) -> dict:
        return {"name": "ENU_TILE", "origin_ecef_m": [float(v) for v in self.origin_ecef_m],
                "R_ecef_from_render": [[float(v) for v in row] for row in self.R_ecef_from_render]}


def grid_mesh(camera, pos_ecef, R_ecef_from_cam, tile: TileFrame, n: int, margin_px: float, h_m: float = 0.0):
    """Vertices (n+1)², render frame, of image rays meeting the ellipsoid raised by ``h_m``; faces (2n², 3)
    counter-clockwise seen from above."""
    # Mitsuba's float32 ray-triangle test is not watertight: a pixel-centre ray exactly on a shared edge can
    # slip through. Irrational offsets (golden ratio) keep the grid lines and diagonals off the pixel lattice.
    g = 0.6180339887498949
    s = np.linspace(-0.5 - margin_px - 0.5 * g, camera.width - 0.5 + margin_px + g, n + 1)
    ln = np.linspace(-0.5 - margin_px - g, camera.height - 0.5 + margin_px + 0.5 * g, n + 1)
    S, L = np.meshgrid(s, ln)
    d_cam = camera.unproject(np.stack([S.ravel(), L.ravel()], -1))
    d = d_cam @ R_ecef_from_cam.T
    t = wgs84.ray_ellipsoid(pos_ecef[None, :], d, h_m)
    if not np.all(np.isfinite(t)):
        raise UserError("camera: the image reaches beyond the Earth's horizon; Earth tiles need every pixel on "
                        "the ground (reduce the field of view or the pointing error)")
    V = tile.to_render(pos_ecef[None, :] + t[:, None] * d)
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, c, e = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    F = np.concatenate([np.stack([a, b, c], -1), np.stack([a, c, e], -1)])
    nz = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])[:, 2]
    if np.median(nz) < 0:
        F = F[:, ::-1]
    return V, F


def land_coverage(tile: TileFrame, region, gshhg, e0: float, n1: float, cell_m: float, shape: tuple[int, int],
                  antialias: int) -> np.ndarray:
    """Land area fraction (H, W) float32 of raster cells: cell (row, col) centred at
    (e0 + (col+½)·cell, n1 − (row+½)·cell) in the tile's east/north plane."""
    import cv2
    import shapely

    H, W = shape
    ss = antialias
    img = np.zeros((H * ss, W * ss), np.uint8)
    shift = 4
    scale = float(1 << shift)
    pieces = [p for g in gshhg.land_in(region) for p in shapely.get_parts(g) if p.geom_type == "Polygon"]

    def to_px(ring_xy):
        lon, lat = np.radians(ring_xy[:, 0]), np.radians(ring_xy[:, 1])
        enu = tile.to_render(wgs84.geodetic_to_ecef(lat, lon))
        col = (enu[:, 0] - e0) / (cell_m / ss) - 0.5
        row = (n1 - enu[:, 1]) / (cell_m / ss) - 0.5
        return np.round(np.stack([col, row], -1) * scale).astype(np.int32)

    if pieces:
        cv2.fillPoly(img, [to_px(np.asarray(p.exterior.coords)) for p in pieces], 255, lineType=cv2.LINE_8, shift=shift)
        holes = [to_px(np.asarray(r.coords)) for p in pieces for r in p.interiors]
        if holes:
            cv2.fillPoly(img, holes, 0, lineType=cv2.LINE_8, shift=shift)
    cov = img.reshape(H, ss, W, ss).astype(np.float32).mean(axis=(1, 3)) / 255.0
    return cov


def texture_uv(V: np.ndarray, e0: float, n1: float, cell_m: float, shape: tuple[int, int]) -> np.ndarray:
    """(u, v) of render-frame vertices for a raster laid out as in :func:`land_coverage`."""
    H, W = shape
    return np.stack([(V[:, 0] - e0) / (W * cell_m), (n1 - V[:, 1]) / (H * cell_m)], -1)


def region_of(V_render: np.ndarray, n: int, tile: TileFrame, pad_deg: float = 0.02):
    """Lon/lat polygon around a grid mesh (its boundary vertices), padded by ``pad_deg``."""
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    loop = np.concatenate([idx[0, :-1], idx[:-1, -1], idx[-1, :0:-1], idx[:0:-1, 0]])
    lat, lon, _ = wgs84.ecef_to_geodetic(tile.to_ecef(V_render[loop]))
    poly = footprint.lonlat_polygons(np.degrees(lon)[None], np.degrees(lat)[None])[0]
    return poly.buffer(pad_deg) if pad_deg > 0 else poly
