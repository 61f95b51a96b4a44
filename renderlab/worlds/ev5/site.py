"""The high-resolution landing site: a square DEM patch laid on the global mesh.

Site frame S: origin o on the global surface above (lat, lon), +z the area-weighted mean facet
normal within half an extent of o, +x east (z_body × z, or body +x at a pole), +y = z × x
(north). Grid point (row j, column i) is at x = x0 + i·c, y = x0 + j·c (x0 = −extent/2) and
height h[j, i] along +z:  p_body = o + R_body_from_site @ [x, y, h].

    h = base + taper · detail

``base`` is the global mesh itself, rasterised along −z onto the grid (exact on its facets), so
the patch border meets the global surface without a step; ``detail`` = craters + boulders
(with a 2–4 m target boulder at the centre) + fractal regolith roughness; ``taper`` is 0 in an
outer strip of 1.5 global facets and rises (smoothstep) to 1 over ``taper_m``. Relative albedo:
the global albedo blended into a correlated field × per-boulder factors with the same taper.

The global mesh must not poke through the patch: global facets with all three vertices inside
the zero-taper strip's inner edge are removed (cut) and every remaining global vertex inside it
is lowered along −z by the patch's deepest detail + 5 cm, so the facets straddling the strip
slope under the patch; global vertices inside the patch's outer strip (where both surfaces
coincide) are lowered by 2 cm, so the global facets' convex kinks stay under the DEM's chords
(the facets straddling the patch edge dip by < 2 cm just outside it; elsewhere outside the patch
the global surface is unchanged).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from renderlab.errors import UserError
from renderlab.worlds.ev5 import terrain
from renderlab.worlds.ev5.shape import GlobalShape

STRIP_DROP_M = 0.02  # global vertices in the patch's outer strip sit this much below the base


@dataclass
class Site:
    """The landing-site DEM (see the module docstring)."""

    origin_m: np.ndarray  # (3,) body frame
    R_body_from_site: np.ndarray  # (3, 3) columns: site x (east), y (north), z (up)
    x0_m: float  # coordinate of the first row/column
    cell_m: float
    heights_m: np.ndarray  # (n, n) float64
    albedo: np.ndarray  # (n, n) float32 relative albedo
    target_center_xy: np.ndarray  # (2,) site x, y of the target boulder
    target_diameter_m: float
    n_boulders: int
    n_craters: int

    @property
    def n(self) -> int:
        return self.heights_m.shape[0]

    @functools.cached_property
    def max_height_m(self) -> float:
        """Highest DEM height (m), computed once per site (every shadow test of every frame needs it)."""
        return float(self.heights_m.max())

    @property
    def extent_m(self) -> float:
        return (self.n - 1) * self.cell_m

    def height_at(self, x, y) -> np.ndarray:
        """Height along site +z of the triangulated DEM at site (x, y), m."""
        return terrain.grid_interp(self.heights_m, self.x0_m, self.cell_m, x, y)

    def albedo_at(self, x, y) -> np.ndarray:
        return terrain.grid_interp(self.albedo, self.x0_m, self.cell_m, x, y)

    def to_body(self, p_site) -> np.ndarray:
        return np.asarray(p_site, float) @ self.R_body_from_site.T + self.origin_m

    def to_site(self, p_body) -> np.ndarray:
        return (np.asarray(p_body, float) - self.origin_m) @ self.R_body_from_site

    def surface_point(self, x, y) -> np.ndarray:
        """Body-frame surface point(s) at site (x, y)."""
        x, y = np.asarray(x, float), np.asarray(y, float)
        return self.to_body(np.stack([x, y, self.height_at(x, y)], -1))

    def mesh(self) -> tuple[np.ndarray, np.ndarray]:
        """Vertices (n², 3) float64 in the body frame and faces (int32) of the DEM."""
        n = self.n
        t = self.x0_m + np.arange(n) * self.cell_m
        R, o = self.R_body_from_site, self.origin_m
        v = np.empty((n, n, 3))
        for k in range(3):
            v[..., k] = o[k] + R[k, 0] * t[None, :] + R[k, 1] * t[:, None] + R[k, 2] * self.heights_m
        return v.reshape(-1, 3), terrain.grid_faces(n)


def _ray_mesh_far_hit(shape: GlobalShape, u: np.ndarray) -> np.ndarray:
    """Farthest intersection of the ray from the body centre along ``u`` with the mesh."""
    v = shape.vertices
    a, b, c = v[shape.faces[:, 0]], v[shape.faces[:, 1]], v[shape.faces[:, 2]]
    e1, e2 = b - a, c - a
    p = np.cross(u, e2)
    det = np.einsum("ij,ij->i", e1, p)
    ok = np.abs(det) > 1e-12
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = -a
    bu = np.einsum("ij,ij->i", s, p) * inv
    q = np.cross(s, e1)
    bv = (q @ u) * inv
    t = np.einsum("ij,ij->i", e2, q) * inv
    hit = ok & (bu >= 0) & (bv >= 0) & (bu + bv <= 1) & (t > 0)
    if not hit.any():
        raise UserError("world.site: the ray from the body centre toward (lat, lon) misses the shape model")
    return u * t[hit].max()


def site_frame(shape: GlobalShape, lat_deg: float, lon_deg: float, extent_m: float):
    """Origin (on the mesh) and R_body_from_site of a site at (lat, lon)."""
    lat, lon = math.radians(lat_deg), math.radians(lon_deg)
    u = np.array([math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)])
    o = _ray_mesh_far_hit(shape, u)
    v = shape.vertices
    tri = v[shape.faces]
    cen = tri.mean(1)
    near = np.linalg.norm(cen - o, axis=1) < extent_m / 2
    nrm = np.cross(tri[near, 1] - tri[near, 0], tri[near, 2] - tri[near, 0]).sum(0)
    z = nrm / np.linalg.norm(nrm)
    x = np.cross([0.0, 0.0, 1.0], z)
    x = x / np.linalg.norm(x) if np.linalg.norm(x) > 1e-6 else np.array([1.0, 0.0, 0.0])
    x = x - (x @ z) * z
    x /= np.linalg.norm(x)
    return o, np.column_stack([x, np.cross(z, x), z])


@dataclass(frozen=True)
class _Grid:
    """The patch's n × n grid: site x (column i) = y (row j) = x0 + i·cell, x0 = −half."""

    n: int
    cell: float
    x0: float

    @property
    def half(self) -> float:
        return -self.x0


def _patch_grid(cfg) -> _Grid:
    n = int(round(cfg.extent_m / cfg.cell_m)) + 1
    return _Grid(n, cfg.cell_m, -(n - 1) * cfg.cell_m / 2)


def _base_surface(shape: GlobalShape, o: np.ndarray, R: np.ndarray, g: _Grid, facet_m: float, cfg):
    """The global mesh rasterised along −z onto the grid.

    Returns
    -------
    vs : ndarray (V, 3)
        Global vertices in site coordinates.
    near_v : ndarray of bool (V,)
        Vertices near the patch (within 3 facets laterally, 50 facets in height).
    base, base_alb : ndarray (n, n)
        Height and albedo of the global surface at the grid points.
    """
    half, n = g.half, g.n
    vs = (shape.vertices - o) @ R
    near_v = (np.abs(vs[:, 0]) < half + 3 * facet_m) & (np.abs(vs[:, 1]) < half + 3 * facet_m) \
        & (np.abs(vs[:, 2]) < half + 50 * facet_m)
    fsel = near_v[shape.faces].all(1)
    tri = vs[shape.faces[fsel]]
    base = np.full((n, n), np.nan)
    base_alb = np.zeros((n, n))
    terrain.rasterize_facets(tri, shape.vertex_albedo[shape.faces[fsel]].astype(float), g.x0, g.cell, n, base,
                             base_alb)
    if np.isnan(base).any():
        raise UserError(f"world.site: the global surface does not cover the {cfg.extent_m:g} m site at "
                        f"({cfg.lat_deg:g}, {cfg.lon_deg:g}) seen along its normal (overhang or hole)")
    return vs, near_v, base, base_alb


def _taper(g: _Grid, w0: float, taper_m: float) -> np.ndarray:
    """(n, n) float32: 0 in the outer strip of width ``w0``, smoothstep to 1 over ``taper_m``."""
    t = g.x0 + np.arange(g.n) * g.cell
    d_edge = g.half - np.maximum(np.abs(t)[None, :], np.abs(t)[:, None])
    s = np.clip((d_edge - w0) / taper_m, 0, 1)
    return (s * s * (3 - 2 * s)).astype(np.float32)


def _stamp_craters(detail: np.ndarray, g: _Grid, cfg, inner: float, rng: np.random.Generator) -> int:
    """Stamp the power-law crater population inside ``|x|, |y| < inner`` into ``detail`` (in place) → count."""
    dc = terrain.power_law_diameters(rng, cfg.crater_density_per_m2, (2 * inner) ** 2, 2.0, cfg.crater_min_m,
                                     cfg.crater_max_m)
    lim = np.maximum(inner - 0.75 * dc, 0)
    cxy = rng.uniform(-1, 1, (len(dc), 2)) * lim[:, None]
    terrain.stamp_craters(detail, g.x0, g.cell, cxy[:, 0].copy(), cxy[:, 1].copy(), dc)
    return len(dc)


def _stamp_boulders(detail: np.ndarray, alb: np.ndarray, g: _Grid, cfg, inner: float,
                    rng: np.random.Generator) -> int:
    """Stamp the target boulder (at the centre) and the power-law boulders into ``detail`` and their albedo
    factors into ``alb`` (in place, biggest first) → number of boulders besides the target."""
    db = terrain.power_law_diameters(rng, cfg.boulder_density_per_m2, (2 * inner) ** 2, cfg.boulder_sfd_slope,
                                     cfg.boulder_min_m, cfg.boulder_max_m)
    bxy = rng.uniform(-1, 1, (len(db), 2)) * np.maximum(inner - db / 2, 0)[:, None]
    keep = np.hypot(bxy[:, 0], bxy[:, 1]) > cfg.target_boulder_m / 2 + db / 2 + 0.1
    db, bxy = db[keep], bxy[keep]
    nb = len(db)
    aspect_b = rng.uniform(0.6, 1.0, nb)
    aspect_c = rng.uniform(0.4, 0.8, nb)
    theta = rng.uniform(0, math.pi, nb)
    bury = rng.uniform(0.05, 0.35, nb)
    factor = np.exp(rng.normal(0.0, 0.15, nb)).astype(np.float32)
    a_t = cfg.target_boulder_m / 2
    order = np.argsort(-db)  # big first: small boulders sit on the ground, not inside big ones
    terrain.stamp_boulders(detail, alb, g.x0, g.cell,
                           np.r_[0.0, bxy[order, 0]], np.r_[0.0, bxy[order, 1]],
                           np.r_[a_t, db[order] / 2], np.r_[0.8 * a_t, db[order] / 2 * aspect_b[order]],
                           np.r_[0.6 * a_t, db[order] / 2 * aspect_c[order]], np.r_[0.3, theta[order]],
                           np.r_[0.15, bury[order]], np.r_[np.float32(1.1), factor[order]])
    return nb


def _surface_detail(g: _Grid, cfg, inner: float, rng_terrain: np.random.Generator,
                    rng_boulders: np.random.Generator):
    """Detail heights (craters, boulders, fractal roughness; (n, n) float64), relative albedo ((n, n) float32:
    boulder factors × correlated field), number of boulders and of craters."""
    detail = np.zeros((g.n, g.n), np.float64)
    n_craters = _stamp_craters(detail, g, cfg, inner, rng_terrain)
    alb = np.ones((g.n, g.n), np.float32)
    nb = _stamp_boulders(detail, alb, g, cfg, inner, rng_boulders)
    detail += terrain.fractal_field(g.n, g.cell, cfg.roughness_hurst, cfg.roughness_rms_m, rng_terrain)
    var = terrain.smooth_field(g.n, g.cell, cfg.albedo_corr_m, rng_terrain)
    var *= np.float32(cfg.albedo_rms)
    var += np.float32(1.0)
    np.clip(var, 0.2, None, out=var)
    alb *= var
    return detail, alb, nb, n_craters


def _cut_global(shape: GlobalShape, vs, near_v, half: float, w0: float, drop: float, R: np.ndarray) -> GlobalShape:
    """The global shape with the facets under the patch cut and the vertices under it lowered (module docstring)."""
    inside = (np.abs(vs[:, 0]) < half - w0) & (np.abs(vs[:, 1]) < half - w0) & near_v
    faces = shape.faces[~inside[shape.faces].all(1)]
    verts = shape.vertices.copy()
    verts[inside] -= drop * R[:, 2]
    # in the outer strip the surfaces coincide; 2 cm lower keeps the global kinks under the DEM's chords
    strip = (np.abs(vs[:, 0]) < half) & (np.abs(vs[:, 1]) < half) & near_v & ~inside
    verts[strip] -= STRIP_DROP_M * R[:, 2]
    used = np.zeros(len(verts), bool)
    used[faces] = True
    remap = np.cumsum(used) - 1
    return GlobalShape(verts[used], remap[faces].astype(np.int32), shape.vertex_albedo[used], shape.radius_fn)


def build_site(shape: GlobalShape, cfg, facet_m: float, rng_terrain: np.random.Generator,
               rng_boulders: np.random.Generator) -> tuple[Site, GlobalShape]:
    """The landing site of ``cfg`` (:class:`EV5Site`) on ``shape`` and the global shape with the
    facets under the patch cut and lowered (module docstring)."""
    g = _patch_grid(cfg)
    o, R = site_frame(shape, cfg.lat_deg, cfg.lon_deg, cfg.extent_m)
    vs, near_v, base, base_alb = _base_surface(shape, o, R, g, facet_m, cfg)
    w0 = 1.5 * facet_m  # the outer strip: 1.5 global facets
    taper = _taper(g, w0, cfg.taper_m)
    inner = g.half - w0 - cfg.taper_m  # features live inside |x|, |y| < inner
    if inner < cfg.target_boulder_m:
        raise UserError(f"world.site.extent_m {cfg.extent_m:g} m is too small: less than the target boulder is left "
                        f"inside the border strip (1.5 global facets = {w0:g} m) and taper_m ({cfg.taper_m:g} m)")
    detail, alb, nb, n_craters = _surface_detail(g, cfg, inner, rng_terrain, rng_boulders)
    heights = base + taper * detail
    albedo = (base_alb * (1 - taper) + base_alb * alb * taper).astype(np.float32)
    drop = max(0.0, -float((taper * detail).min())) + 0.05
    del detail, alb, taper, base_alb
    cut = _cut_global(shape, vs, near_v, g.half, w0, drop, R)
    site = Site(o, R, float(g.x0), float(g.cell), heights, albedo, np.zeros(2), float(cfg.target_boulder_m), nb,
                n_craters)
    return site, cut
