"""The landmark catalog a ground stereophotoclinometry (SPC) survey would uplink.

Which landmarks serve which range: a maplet correlates best when its grid spacing is about the
image's ground sample distance (GSD = range / f_px; gsd_ratio ≈ 1). With the ARRM-like camera
(1024², ~0.2 mrad pixels: 1 cm at 50 m, 4 cm at 200 m, 20 cm at 1 km) the default tiers are
``regional`` (0.20 m spacing, for ~1 km–400 m), ``approach`` (0.05 m, ~250–100 m) and ``site``
(0.03 m, 50 m and below; the survey maps the candidate sites to 3 cm, Wright et al. §"Concept
of operations"). Retina loads per landmark a DEM of relative heights, a relative albedo, the
body-fixed centre and the body→DEM frame (§"Maplet Pre-Processing").

A maplet is derived from the truth terrain, never copied from it:

1. centre c = truth surface point at a seeded position in the tier's disc (≥ half a maplet apart);
2. frame: +z = normal of the least-squares plane through the truth heights over the footprint,
   +x = site east projected, +y = z × x;
3. truth heights resampled at the maplet spacing: the mean, over k × k sub-points of each maplet
   cell (k = spacing / site cell, ≤ 8), of the truth surface height along maplet +z: the top-most
   intersection of the line along maplet +z with the site DEM (what the survey sees from above,
   also on steep boulder flanks);
4. + mapping error: white noise filtered by a Gaussian of ``mapping_error_corr_cells`` cells and
   scaled by the kernel's L2 norm, so its rms is ``mapping_error_m`` in expectation;
5. relative albedo: the same cell means of the truth albedo, normalised to mean 1, times
   (1 + ``albedo_error_rms`` · white noise).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from scipy.ndimage import gaussian_filter

from renderlab.geometry.maplet import Maplet
from renderlab.worlds.ev5.site import Site


def place_landmarks(tier, rng: np.random.Generator) -> np.ndarray:
    """(m, 2) site (x, y) of the tier's landmarks: uniform in a disc, ≥ half a maplet apart
    (fewer than ``count`` if the disc is full)."""
    sep = 0.5 * (tier.size - 1) * tier.spacing_m
    out: list[np.ndarray] = []
    for _ in range(200 * max(tier.count, 1)):
        if len(out) >= tier.count:
            break
        r = tier.radius_m * math.sqrt(rng.random())
        a = 2 * math.pi * rng.random()
        p = np.array([r * math.cos(a), r * math.sin(a)])
        if all(np.hypot(*(p - q)) >= sep for q in out):
            out.append(p)
    return np.array(out).reshape(-1, 2)


def maplet_frame(site: Site, xy: np.ndarray, half_width_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Centre (body) and R_body_from_maplet of a landmark at site ``xy`` (plane fit over the footprint)."""
    t = np.linspace(-half_width_m, half_width_m, 21)
    X, Y = np.meshgrid(xy[0] + t, xy[1] + t)
    H = site.height_at(X.ravel(), Y.ravel())
    A = np.column_stack([X.ravel() - xy[0], Y.ravel() - xy[1], np.ones(X.size)])
    gx, gy, _ = np.linalg.lstsq(A, H, rcond=None)[0]
    z = np.array([-gx, -gy, 1.0])
    z /= np.linalg.norm(z)
    x = np.array([1.0, 0.0, 0.0]) - z[0] * z
    x /= np.linalg.norm(x)
    R_site_from_maplet = np.column_stack([x, np.cross(z, x), z])
    centre = site.surface_point(xy[0], xy[1])
    return centre, site.R_body_from_site @ R_site_from_maplet


@numba.njit(cache=True)
def _dem_height(heights, x0, cell, x, y):  # pragma: no cover - numba
    """The triangulated DEM at site (x, y), clamped to its border (as :func:`terrain.grid_interp`)."""
    n = heights.shape[0]
    u = min(max((x - x0) / cell, 0.0), n - 1.0)
    v = min(max((y - x0) / cell, 0.0), n - 1.0)
    i, j = min(int(u), n - 2), min(int(v), n - 2)
    fx, fy = u - i, v - j
    if fx >= fy:
        return heights[j, i] + fx * (heights[j, i + 1] - heights[j, i]) + fy * (heights[j + 1, i + 1] - heights[j, i + 1])
    return heights[j, i] + fy * (heights[j + 1, i] - heights[j, i]) + fx * (heights[j + 1, i + 1] - heights[j + 1, i])


@numba.njit(cache=True)
def _top_crossing(heights, x0, cell, bx, by, bz, zx, zy, zz, zmax, zmin):  # pragma: no cover - numba
    """Largest h with b + h z on the DEM, for each base point b (site frame) and unit z (zz > 0):
    march down from above the DEM's top in steps that move ≤ ½ cell sideways, then bisect."""
    out = np.empty(len(bx))
    dh = 0.5 * cell / max(math.sqrt(zx * zx + zy * zy), 0.05)
    for k in range(len(bx)):
        hi = (zmax - bz[k]) / zz + dh  # above every DEM point
        stop = (zmin - bz[k]) / zz - dh  # below every DEM point
        lo = hi
        found = False
        while lo > stop:
            lo = hi - dh
            if bz[k] + lo * zz <= _dem_height(heights, x0, cell, bx[k] + lo * zx, by[k] + lo * zy):
                found = True
                break
            hi = lo
        if not found:
            out[k] = np.nan
            continue
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            if bz[k] + mid * zz <= _dem_height(heights, x0, cell, bx[k] + mid * zx, by[k] + mid * zy):
                lo = mid
            else:
                hi = mid
        out[k] = 0.5 * (lo + hi)
    return out


def truth_heights(site: Site, centre_body: np.ndarray, R_body_from_maplet: np.ndarray,
                  u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Height along maplet +z of the truth surface above maplet-frame points (u, v) (any shape): the
    top-most intersection of the line through (u, v, 0) along maplet +z with the site DEM, i.e. the
    surface seen from above along −z (exact on the DEM's facets, also on steep boulder flanks)."""
    R_sm = site.R_body_from_site.T @ R_body_from_maplet  # site ← maplet
    c = site.to_site(centre_body)
    u, v = np.asarray(u, float), np.asarray(v, float)
    base = (c + np.stack([u, v, np.zeros_like(u)], -1) @ R_sm.T).reshape(-1, 3)
    zs = R_sm[:, 2]
    if zs[2] <= 0.05:
        raise ValueError("maplet +z must point up out of the site")
    h = _top_crossing(site.heights_m, site.x0_m, site.cell_m, base[:, 0].copy(), base[:, 1].copy(),
                      base[:, 2].copy(), float(zs[0]), float(zs[1]), float(zs[2]),
                      float(site.heights_m.max()), float(site.heights_m.min()))
    return h.reshape(u.shape)


def cell_means(site: Site, centre_body, R_body_from_maplet, spacing: float, n: int):
    """Truth heights and relative albedo averaged over each maplet cell (k × k sub-points)."""
    k = int(min(8, max(1, round(spacing / site.cell_m))))
    g = (np.arange(n) - (n - 1) / 2) * spacing
    sub = ((np.arange(k) + 0.5) / k - 0.5) * spacing
    U = g[None, :, None, None] + sub[None, None, None, :]
    V = g[:, None, None, None] + sub[None, None, :, None]
    U, V = np.broadcast_arrays(U, V)  # (n, n, k, k): row j, column i, sub-row, sub-column
    h = truth_heights(site, centre_body, R_body_from_maplet, U, V)
    p_site = site.to_site(np.stack([U, V, h], -1) @ R_body_from_maplet.T + centre_body)
    a = site.albedo_at(p_site[..., 0], p_site[..., 1])
    return h.mean(axis=(2, 3)), a.mean(axis=(2, 3))


def correlated_error(n: int, rms: float, corr_cells: float, rng: np.random.Generator) -> np.ndarray:
    """(n, n) Gaussian error field: white noise ⊛ Gaussian(σ = corr_cells), unit-variance kernel × rms."""
    if corr_cells <= 0:
        return rng.normal(0.0, rms, (n, n))
    pad = int(math.ceil(4 * corr_cells))
    white = rng.standard_normal((n + 2 * pad, n + 2 * pad))
    delta = np.zeros((2 * pad + 1, 2 * pad + 1))
    delta[pad, pad] = 1.0
    kernel_l2 = math.sqrt(float((gaussian_filter(delta, corr_cells, mode="constant", truncate=4.0) ** 2).sum()))
    field = gaussian_filter(white, corr_cells, mode="constant", truncate=4.0)[pad:pad + n, pad:pad + n]
    return field * (rms / kernel_l2)


def build_catalog(site: Site, world, rng_place: np.random.Generator, rng_error: np.random.Generator):
    """Maplets of every tier and a {landmark_id: tier name} map. Ids count up over the tiers."""
    maplets, tiers = [], {}
    for tier in world.landmarks:
        pts = place_landmarks(tier, rng_place)
        half = (tier.size - 1) / 2 * tier.spacing_m
        for xy in pts:
            lid = len(maplets)
            centre, R = maplet_frame(site, xy, half)
            h, a = cell_means(site, centre, R, tier.spacing_m, tier.size)
            h = h + correlated_error(tier.size, world.mapping_error_m, world.mapping_error_corr_cells, rng_error)
            a = a / a.mean() * (1.0 + world.albedo_error_rms * rng_error.standard_normal(a.shape))
            maplets.append(Maplet(lid, centre, R, float(tier.spacing_m), h, a))
            tiers[lid] = tier.name
    return maplets, tiers
