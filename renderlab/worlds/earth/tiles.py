r"""Local tangent tiles: the ground (and cloud layer) of one Earth frame as triangle meshes in ENU metres.

Why: Mitsuba traces in float32; Earth-centred coordinates (≈ 6.4e6 m) would move secondary rays by
hundreds of metres. Each frame is rendered in the East-North-Up frame of the point where its boresight
meets the ellipsoid: ``p_ecef = R_ecef_from_render @ p_render + origin_ecef``.

The ground mesh is a G×G grid of image rays (the image widened by a margin) intersected with the WGS-84
ellipsoid, so its vertices lie exactly on the ellipsoid (chord sag d²/8R ≈ 2 m for 9 km cells). Its albedo
texture is a raster in the tile's (east, north) plane: every facet is planar, so (e, n) is linear on it and
the texture coordinate of any hit point is exact. The raster is GSHHG land coverage (``antialias``² sub-cells
per cell sampled at their centres, i.e. the area fraction of land in the cell) at ≤ GSD/``texture_oversample``.
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


def fill_even_odd(shape: tuple[int, int], rings: list[np.ndarray]) -> np.ndarray:
    """Bool raster (H, W): pixels whose *centre* lies inside the rings (even-odd rule; holes are rings too).

    Pixel (row, col) has its centre at (x, y) = (col, row). Exact scanline fill, vectorised over all edges: an
    edge crossing row r (half-open in y, so a vertex on a row is counted once) at x toggles every pixel with
    col ≥ x; the parity of the toggles is accumulated along the row. Unlike ``cv2.fillPoly``, which also fills
    the pixels its boundary lines touch (measured: the filled area exceeds the polygon's by 0.45 px x its
    perimeter), pixel-centre sampling is unbiased, so the land/water boundary of the coverage raster sits on the
    polygon's edge on average.
    """
    H, W = shape
    out = np.zeros((H, W + 1), np.uint8)
    if rings:
        a = np.concatenate([r[:-1] for r in rings if len(r) > 1])
        b = np.concatenate([r[1:] for r in rings if len(r) > 1])
        ylo, yhi = np.minimum(a[:, 1], b[:, 1]), np.maximum(a[:, 1], b[:, 1])
        r0 = np.clip(np.ceil(ylo), 0, H).astype(np.int64)
        r1 = np.clip(np.ceil(yhi), 0, H).astype(np.int64)
        n = r1 - r0
        keep = n > 0
        a, b, r0, n = a[keep], b[keep], r0[keep], n[keep]
        e = np.repeat(np.arange(len(n)), n)
        row = r0[e] + (np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n))
        x = a[e, 0] + (row - a[e, 1]) * (b[e, 0] - a[e, 0]) / (b[e, 1] - a[e, 1])
        col = np.clip(np.ceil(x), 0, W).astype(np.int64)
        idx, cnt = np.unique(row * (W + 1) + col, return_counts=True)
        out.reshape(-1)[idx[cnt % 2 == 1]] = 1
        np.bitwise_xor.accumulate(out, axis=1, out=out)
    return out[:, :W].astype(bool)


def land_coverage(tile: TileFrame, region, gshhg, e0: float, n1: float, cell_m: float, shape: tuple[int, int],
                  antialias: int) -> np.ndarray:
    """Land area fraction (H, W) float32 of raster cells: cell (row, col) centred at
    (e0 + (col+½)·cell, n1 − (row+½)·cell) in the tile's east/north plane; ``antialias``² sub-cells per cell,
    each land when its centre is (:func:`fill_even_odd`)."""
    import shapely

    H, W = shape
    ss = antialias
    pieces = [p for g in gshhg.land_in(region) for p in shapely.get_parts(g) if p.geom_type == "Polygon"]

    def to_px(ring_xy):
        lon, lat = np.radians(ring_xy[:, 0]), np.radians(ring_xy[:, 1])
        enu = tile.to_render(wgs84.geodetic_to_ecef(lat, lon))
        col = (enu[:, 0] - e0) / (cell_m / ss) - 0.5
        row = (n1 - enu[:, 1]) / (cell_m / ss) - 0.5
        return np.stack([col, row], -1)

    rings = [to_px(np.asarray(r.coords)) for p in pieces for r in (p.exterior, *p.interiors)]
    img = fill_even_odd((H * ss, W * ss), rings)
    return img.reshape(H, ss, W, ss).mean(axis=(1, 3), dtype=np.float32)


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
