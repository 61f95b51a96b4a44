"""The landing site as tiles with levels of detail: per frame, only the tiles in the frustum, each at the
coarsest level whose facets still project to at most ``lod_pixels`` pixels.

Tiles: the site's (n−1)² DEM cells split into squares of ``tile_cells`` (a power of two) cells; the last
row/column of tiles takes the remainder. Tile (r, c) covers cell columns ``edges[c] .. edges[c+1]`` and
rows ``edges[r] .. edges[r+1]`` (its border vertices are shared with its neighbours).

Level L of a tile is the DEM decimated by cell-size doubling: its vertices are the full-resolution DEM
vertices at a stride of 2^L cells in both directions (point sampling, no smoothing), triangulated like the
DEM (diagonal v00–v11, :func:`renderlab.worlds.ev5.terrain.grid_faces`). L is at most log2(tile_cells) and
such that 2^L divides both sides of the tile, so every coarse cell is square; then every coarse edge lies on
fine edges and the height difference between the two piecewise-linear surfaces is linear on each fine facet:
its maximum over the tile is exactly the maximum over the fine vertices, which :meth:`TiledSite.error`
computes (the *LOD height error bound* of the tile at that level, along the site normal).

Level choice (:meth:`TiledSite.select`): d = distance from the camera centre to the tile's bounding box
(site frame, heights included), GSD = d / σ with σ the largest singular value of the camera's 2×2 pixel map
K (Retina eq. 4; the finest pixel scale at the principal point, distortion not included); L = the largest
level with cell·2^L ≤ lod_pixels·GSD. Facet budget (``facets_per_pixel``, optional): where the frame's tiles
would hold more than ``facets_per_pixel · W · H`` facets (lod_pixels = 1 puts 2–8 facets in a pixel, more where
tiles reach beyond the image), the facet limit is raised from lod_pixels to the smallest value (bisection on its
log) whose levels fit — the same rule with a coarser limit, a pure function of the pose; the manifest's
``ev5.lod.lod_pixels_used`` records it and ``max_height_error_m`` the resulting bound. Frustum: the tile's box corners against the pyramid spanned by the
image border unprojected (:meth:`CameraModel.unproject` of 32 points per side, bounding box of x/z, y/z,
widened by 2 px); a tile is dropped when all eight corners are behind the camera or outside one face.
A camera whose border does not unproject in front (wide fisheye) keeps every tile.

Cracks: neighbours at different levels meet along polylines that differ by at most the sum of their border
errors. Each tile hangs a skirt (vertical wall along its border, outward facing) of depth
2·e_b(L) + cell, e_b(L) the largest border error of its levels ≤ L, so the coarser tile's skirt closes the gap.

Truth consistency: the rendered AOVs (position, range, normal) of the site come from the frame's tiles at
their levels (recorded per frame in the manifest, ``ev5.lod``); the landmark catalog, the maplets, the
landmark centres and the shadow march of ``landmark_truth`` use the full-resolution DEM (level 0). The
difference of the two is measured by ray casting in ``tests/test_ev5_tiles.py``: |range(tiles) −
range(full DEM)| at the frame's pixel centres, in units of the GSD; the test requires ≤ 0.25 GSD on 99 % of
site pixels (measured on the tiny test world at 100 m, level 1: median 0.002, p99 0.086, p99.9 0.24 GSD;
with lod_pixels = 8: p99 0.85, which the test rejects). That is far inside the occlusion tolerance of
:mod:`renderlab.worlds.ev5.landmark_truth` (max(spacing, 3 GSD)), so visibility flags do not depend on the
level; ``aov_offset_m`` includes the level's height error (bounded per frame by ``ev5.lod.max_height_error_m``).

Who uses the tiles: Mitsuba's ``tile_design = "two"`` and ``"merged"`` (and its CUDA variants). Its default on LLVM
variants marches the full DEM instead (:mod:`renderlab.render.mitsuba_dem`) and marks the surface
``traced_whole``; :meth:`TiledSite.lod_summary` then records the full DEM, with no height error.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from renderlab.worlds.ev5.terrain import rect_faces


@dataclass(frozen=True, order=True)
class TileKey:
    """Tile (row, col) of the site at level ``level``."""

    row: int
    col: int
    level: int

    @property
    def name(self) -> str:
        return f"r{self.row}c{self.col}L{self.level}"


def _coarse(h: np.ndarray, stride: int, v: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Height of the stride-decimated triangulated grid of ``h`` at fine vertices (row ``v``, column ``u``)."""
    c = h[::stride, ::stride]
    i, j = np.minimum(u // stride, c.shape[1] - 2), np.minimum(v // stride, c.shape[0] - 2)
    FX, FY = (u - i * stride) / stride, (v - j * stride) / stride
    h00, h01, h10, h11 = c[j, i], c[j, i + 1], c[j + 1, i], c[j + 1, i + 1]
    return np.where(FX >= FY, h00 + FX * (h01 - h00) + FY * (h11 - h01), h00 + FY * (h10 - h00) + FX * (h11 - h10))


def decimation_error(h: np.ndarray, stride: int) -> tuple[float, float]:
    """(max over the tile, max over its border) of |h − h_L| at the fine vertices of the tile ``h``
    ((ny, nx), sides divisible by ``stride``), h_L the stride-decimated triangulated grid."""
    ny, nx = h.shape
    if stride == 1:
        return 0.0, 0.0
    V, U = np.meshgrid(np.arange(ny), np.arange(nx), indexing="ij")
    d = np.abs(h - _coarse(h, stride, V, U))
    border = max(d[0].max(), d[-1].max(), d[:, 0].max(), d[:, -1].max())
    return float(d.max()), float(border)


def border_error(h: np.ndarray, stride: int) -> float:
    """The border part of :func:`decimation_error` (the same arithmetic, at the border vertices only)."""
    ny, nx = h.shape
    if stride == 1:
        return 0.0
    u, v = np.arange(nx), np.arange(ny)
    V = np.concatenate([np.zeros(nx, np.int64), np.full(nx, ny - 1), v, v])
    U = np.concatenate([u, u, np.zeros(ny, np.int64), np.full(ny, nx - 1)])
    return float(np.abs(h[V, U] - _coarse(h, stride, V, U)).max())


def _pow2_divisor_level(n: int, cap: int) -> int:
    level = 0
    while level < cap and n % (2 ** (level + 1)) == 0:
        level += 1
    return level


class TiledSite:
    """The site DEM of :class:`~renderlab.worlds.ev5.site.Site` as tiles with levels (module docstring).

    Implements the tiled-surface contract (:class:`renderlab.contracts.tiled.TiledSurface`): ``select``,
    ``tile_body``, ``full_body``, ``state``. ``law``/``albedo`` and the body pose are those of the site body.
    """

    def __init__(self, site, tile_cells: int, lod_pixels: float, *, body_id: int, name: str, law, albedo: float,
                 facets_per_pixel: float | None = None):
        self.site, self.tile_cells, self.lod_pixels = site, int(tile_cells), float(lod_pixels)
        self.facets_per_pixel = None if facets_per_pixel is None else float(facets_per_pixel)
        self.last_lod_pixels = self.lod_pixels  # the facet limit (px) the last selection used
        self.body_id, self.name, self.law, self.albedo = int(body_id), name, law, float(albedo)
        cells = site.n - 1
        self.edges = np.r_[np.arange(0, cells, self.tile_cells), cells].astype(np.int64)
        self.n_tiles = len(self.edges) - 1
        cap = int(round(math.log2(self.tile_cells)))
        sizes = np.diff(self.edges)
        self._axis_level = np.array([_pow2_divisor_level(int(s), cap) for s in sizes])
        e, h = self.edges, site.heights_m
        self.zrange = np.empty((self.n_tiles, self.n_tiles, 2))
        for r in range(self.n_tiles):
            for c in range(self.n_tiles):
                t = h[e[r]:e[r + 1] + 1, e[c]:e[c + 1] + 1]
                self.zrange[r, c] = float(t.min()), float(t.max())
        self._err: dict[tuple[int, int, int], tuple[float, float]] = {}
        self.traced_whole = False  # set by a backend that marches the full DEM (renderlab.contracts.tiled)
        self._border: dict[tuple[int, int, int], float] = {}  # border bounds of the levels below a tile's own

    # ------------------------------------------------------------------ geometry of the tiles
    def max_level(self, row: int, col: int) -> int:
        return int(min(self._axis_level[row], self._axis_level[col]))

    def _boxes(self) -> np.ndarray:
        """(T, T, 2, 3) site-frame bounding boxes (min, max corner) of the tiles."""
        s = self.site
        t = s.x0_m + self.edges * s.cell_m
        box = np.empty((self.n_tiles, self.n_tiles, 2, 3))
        box[..., 0, 0], box[..., 1, 0] = t[None, :-1], t[None, 1:]
        box[..., 0, 1], box[..., 1, 1] = t[:-1, None], t[1:, None]
        box[..., 0, 2], box[..., 1, 2] = self.zrange[..., 0], self.zrange[..., 1]
        return box

    def corners_body(self) -> np.ndarray:
        """(T, T, 8, 3) body-frame corners of the tiles' bounding boxes."""
        box = self._boxes()
        idx = np.array([[a, b, c] for a in (0, 1) for b in (0, 1) for c in (0, 1)])
        pts = np.stack([box[..., idx[:, k], k] for k in range(3)], -1)
        return self.site.to_body(pts)

    def error(self, key: TileKey) -> tuple[float, float]:
        """(height error bound over the tile, over its border) of ``key``'s level vs the full DEM, m."""
        k = (key.row, key.col, key.level)
        if k not in self._err:
            e = self.edges
            h = np.asarray(self.site.heights_m[e[key.row]:e[key.row + 1] + 1, e[key.col]:e[key.col + 1] + 1], float)
            self._err[k] = decimation_error(h, 2 ** key.level)
        return self._err[k]

    def border_error(self, key: TileKey) -> float:
        """The height error bound of ``key``'s level along the tile's border, m (``error(key)[1]``, computed on the
        border alone unless the tile's full bound is known)."""
        k = (key.row, key.col, key.level)
        if k in self._err:
            return self._err[k][1]
        if k not in self._border:
            e = self.edges
            h = np.asarray(self.site.heights_m[e[key.row]:e[key.row + 1] + 1, e[key.col]:e[key.col + 1] + 1], float)
            self._border[k] = border_error(h, 2 ** key.level)
        return self._border[k]

    def skirt_depth(self, key: TileKey) -> float:
        eb = max(self.border_error(TileKey(key.row, key.col, lv)) for lv in range(key.level + 1))
        return 2.0 * eb + self.site.cell_m

    # ------------------------------------------------------------------ per frame
    def select(self, camera, pose, R_render_from_body=None, center_m=None) -> list[TileKey]:
        """The tiles in the frustum of ``camera`` at ``pose`` (render frame), each at its level; with a facet budget,
        coarsened until the frame renders at most ``facets_per_pixel`` facets per image pixel."""
        R_rb = np.eye(3) if R_render_from_body is None else np.asarray(R_render_from_body, float)
        c_rb = np.zeros(3) if center_m is None else np.asarray(center_m, float)
        R = pose.rotation.as_matrix()  # render ← camera
        t = np.asarray(pose.position_m, float)
        corners = self.corners_body() @ R_rb.T + c_rb
        p = (corners - t) @ R  # camera frame
        rows, cols = np.nonzero(_in_frustum(camera, p))
        t_site = self.site.to_site(R_rb.T @ (t - c_rb))
        box = self._boxes()
        d = np.linalg.norm(np.maximum(np.maximum(box[..., 0, :] - t_site, t_site - box[..., 1, :]), 0.0), axis=-1)
        sigma = float(np.linalg.norm(np.array([[camera.fx, camera.skew], [camera.skew_yx, camera.fy]]), 2))
        gsd = (d / sigma)[rows, cols]
        cap = np.minimum(self._axis_level[rows], self._axis_level[cols])
        tau = self.lod_pixels
        level = self._levels(gsd, tau, cap)
        if self.facets_per_pixel is not None:
            budget = self.facets_per_pixel * camera.width * camera.height
            if self._facets(rows, cols, level) > budget:
                lo, hi = math.log2(tau), math.log2(tau) + 2.0 * cap.max(initial=0) + 8.0
                for _ in range(40):  # the smallest facet limit (px) whose levels fit the budget (facets fall with it)
                    mid = 0.5 * (lo + hi)
                    lo, hi = (lo, mid) if self._facets(rows, cols, self._levels(gsd, 2.0 ** mid, cap)) <= budget \
                        else (mid, hi)
                tau = 2.0 ** hi
                level = self._levels(gsd, tau, cap)
        self.last_lod_pixels = float(tau)
        return [TileKey(int(r), int(c), int(lv)) for r, c, lv in zip(rows, cols, level)]

    def _levels(self, gsd: np.ndarray, lod_pixels: float, cap: np.ndarray) -> np.ndarray:
        """Per tile the largest level with cell·2^L ≤ lod_pixels·GSD, within 0 … its cap."""
        with np.errstate(divide="ignore"):
            level = np.floor(np.log2(np.maximum(lod_pixels * gsd, 1e-300) / self.site.cell_m))
        return np.clip(level, 0, cap).astype(np.int64)

    def _facets(self, rows: np.ndarray, cols: np.ndarray, level: np.ndarray) -> int:
        """Facets (skirts included) of tiles (rows, cols) at ``level``, as :meth:`tile_mesh` builds them."""
        e = self.edges
        ny = (e[rows + 1] - e[rows]) // 2 ** level
        nx = (e[cols + 1] - e[cols]) // 2 ** level
        return int(np.sum(2 * ny * nx + 4 * (ny + nx)))

    def tile_mesh(self, key: TileKey) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Body-frame vertices (float64), faces (int32) and relative albedo of a tile at its level, skirt included."""
        s, e, st = self.site, self.edges, 2 ** key.level
        rows = np.arange(e[key.row], e[key.row + 1] + 1, st)
        cols = np.arange(e[key.col], e[key.col + 1] + 1, st)
        h = np.asarray(s.heights_m[np.ix_(rows, cols)], float)
        a = np.asarray(s.albedo[np.ix_(rows, cols)], np.float32)
        ny, nx = h.shape
        X, Y = np.meshgrid(s.x0_m + cols * s.cell_m, s.x0_m + rows * s.cell_m)
        top = np.stack([X, Y, h], -1).reshape(-1, 3)
        idx = np.arange(ny * nx).reshape(ny, nx)  # border loop, counter-clockwise seen from +z
        loop = np.r_[idx[0, :-1], idx[:-1, -1], idx[-1, :0:-1], idx[:0:-1, 0]]
        low = top[loop] - [0.0, 0.0, self.skirt_depth(key)]
        a_ = loop
        b_ = np.roll(loop, -1)
        a2 = ny * nx + np.arange(len(loop))
        b2 = np.roll(a2, -1)
        skirt = np.concatenate([np.column_stack([a_, b2, b_]), np.column_stack([a_, a2, b2])])
        V = s.to_body(np.concatenate([top, low]))
        F = np.concatenate([rect_faces(ny, nx), skirt]).astype(np.int32)
        return V, F, np.concatenate([a.ravel(), a.ravel()[loop]])

    # ------------------------------------------------------------------ bodies
    def _body(self, vertices=None, faces=None, vertex_albedo=None):
        from renderlab.render.scene import BodySpec

        return BodySpec(name=self.name, body_id=self.body_id, shape="trimesh", center_m=np.zeros(3),
                        R_render_from_body=np.eye(3), law=self.law, albedo=self.albedo, vertices=vertices,
                        faces=faces, vertex_albedo=vertex_albedo)

    def tile_body(self, key: TileKey):
        """The :class:`~renderlab.render.scene.BodySpec` of one tile at its level."""
        return self._body(*self.tile_mesh(key))

    def full_body(self):
        """The full-resolution site as one body (the untiled path, for renderers without tiles)."""
        v, f = self.site.mesh()
        return self._body(v, f, np.asarray(self.site.albedo).reshape(-1))

    def state(self) -> dict:
        out = self._body().state()
        out.update(shape="trimesh_tiles", n_faces=int(2 * (self.site.n - 1) ** 2), tile_cells=self.tile_cells,
                   lod_pixels=self.lod_pixels, facets_per_pixel=self.facets_per_pixel)
        return out

    def lod_summary(self, keys: list[TileKey]) -> dict:
        """What a frame rendered: tiles per level, facets (skirts included), the largest height error bound; where
        the backend traced the full DEM (``traced_whole``), that: no tiles, every facet, no height error."""
        if self.traced_whole:
            return {"tracer": "dem_march", "tiles": 0, "levels": {}, "n_faces": 2 * (self.site.n - 1) ** 2,
                    "max_height_error_m": 0.0, "cell_m": self.site.cell_m}
        levels: dict[str, int] = {}
        n_faces = 0
        err = 0.0
        for k in keys:
            levels[str(k.level)] = levels.get(str(k.level), 0) + 1
            e = self.edges
            ny = (e[k.row + 1] - e[k.row]) // 2 ** k.level
            nx = (e[k.col + 1] - e[k.col]) // 2 ** k.level
            n_faces += int(2 * ny * nx + 4 * (ny + nx))
            err = max(err, self.error(k)[0])
        out = {"tiles": len(keys), "levels": dict(sorted(levels.items())), "n_faces": n_faces,
               "max_height_error_m": err, "cell_m": self.site.cell_m, "lod_pixels": self.lod_pixels}
        if self.facets_per_pixel is not None:  # the budget and the facet limit it set for this frame
            out.update(facets_per_pixel=self.facets_per_pixel, lod_pixels_used=self.last_lod_pixels)
        return out


def _in_frustum(camera, p: np.ndarray) -> np.ndarray:
    """(T, T) bool: boxes with camera-frame corners ``p`` (T, T, 8, 3) not wholly outside the view pyramid."""
    W, H = camera.width, camera.height
    u = np.linspace(-0.5, W - 0.5, 32)
    v = np.linspace(-0.5, H - 0.5, 32)
    border = np.concatenate([np.column_stack([u, np.full_like(u, -0.5)]), np.column_stack([u, np.full_like(u, H - 0.5)]),
                             np.column_stack([np.full_like(v, -0.5), v]), np.column_stack([np.full_like(v, W - 0.5), v])])
    with np.errstate(invalid="ignore", divide="ignore"):
        d = np.asarray(camera.unproject(border), float)
    if not np.all(np.isfinite(d)) or np.any(d[:, 2] <= 1e-6):
        return np.ones(p.shape[:2], bool)
    x, y = d[:, 0] / d[:, 2], d[:, 1] / d[:, 2]
    m = 2.0 / min(camera.fx, camera.fy)
    xmin, xmax, ymin, ymax = x.min() - m, x.max() + m, y.min() - m, y.max() + m
    X, Y, Z = p[..., 0], p[..., 1], p[..., 2]
    out = (Z <= 0).all(-1)
    out |= (X > xmax * Z).all(-1) | (X < xmin * Z).all(-1) | (Y > ymax * Z).all(-1) | (Y < ymin * Z).all(-1)
    return ~out
