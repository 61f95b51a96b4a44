"""Numerical kernels of the landing-site terrain: fractal fields, craters, boulders, rasterised facets.

* Regolith roughness: a Gaussian random field with a power-law spectrum P(k) ∝ k^−2(H+1)
  (Hurst exponent H: a fractional-Brownian surface), made by filtering white noise in Fourier space.
* Craters (simple bowls): depth 0.2 D, rim 0.04 D, h(r) = d((r/R)² − 1) + rim inside, rim·(R/r)³
  outside, faded to 0 at 1.5 R; diameters from N(>D) ∝ D^−2.
* Boulders: half-ellipsoids (random aspect, orientation, partly buried), diameters from the
  cumulative power law N(>D) ∝ D^−α (α ≈ 3, as counted on Itokawa and Bennu), each with its own
  albedo factor; heights are max(ground, boulder top).
* ``rasterize_facets``: the height (along the site normal) and albedo of a triangle mesh at every
  grid point, by 2-D barycentric interpolation of the facets projected on the site plane — how the
  site's base surface is taken from the global mesh exactly.

Pure numpy / numba; every random draw from the caller's ``numpy.random.Generator``.
"""

from __future__ import annotations

import math

import numba
import numpy as np


def fractal_field(n: int, cell_m: float, hurst: float, rms: float, rng: np.random.Generator) -> np.ndarray:
    """(n, n) float32 periodic Gaussian field with spectrum ∝ k^−2(H+1), scaled to rms ``rms``."""
    if rms == 0:
        return np.zeros((n, n), np.float32)
    white = rng.standard_normal((n, n), dtype=np.float32)
    spec = np.fft.rfft2(white)
    del white
    ky = np.fft.fftfreq(n, cell_m).astype(np.float32)[:, None]
    kx = np.fft.rfftfreq(n, cell_m).astype(np.float32)[None, :]
    k = np.sqrt(kx * kx + ky * ky)
    k[0, 0] = np.inf
    spec *= k ** np.float32(-(hurst + 1.0))
    del k
    out = np.fft.irfft2(spec, s=(n, n)).astype(np.float32)
    out -= out.mean()
    out *= np.float32(rms / max(float(np.sqrt(np.mean(out.astype(np.float64) ** 2))), 1e-30))
    return out


def smooth_field(n: int, cell_m: float, corr_m: float, rng: np.random.Generator) -> np.ndarray:
    """(n, n) float32 periodic Gaussian field of unit rms with a Gaussian correlation of length ``corr_m``."""
    white = rng.standard_normal((n, n), dtype=np.float32)
    spec = np.fft.rfft2(white)
    del white
    ky = np.fft.fftfreq(n, cell_m).astype(np.float32)[:, None]
    kx = np.fft.rfftfreq(n, cell_m).astype(np.float32)[None, :]
    spec *= np.exp(np.float32(-2 * math.pi ** 2 * corr_m ** 2) * (kx * kx + ky * ky))
    out = np.fft.irfft2(spec, s=(n, n)).astype(np.float32)
    out -= out.mean()
    out /= np.float32(max(float(out.std()), 1e-30))
    return out


def power_law_diameters(rng: np.random.Generator, density_1m: float, area_m2: float, slope: float,
                        d_min: float, d_max: float) -> np.ndarray:
    """Diameters with cumulative density N(>D) = density_1m · D^−slope per m², truncated to [d_min, d_max]."""
    expected = density_1m * area_m2 * (d_min ** -slope - d_max ** -slope)
    n = int(rng.poisson(max(expected, 0.0)))
    u = rng.random(n)
    a, b = d_min ** -slope, d_max ** -slope
    return (a - u * (a - b)) ** (-1.0 / slope)


@numba.njit(cache=True)
def stamp_craters(h, x0, cell, cx, cy, diam):  # pragma: no cover - numba
    """Add simple-crater profiles to the height grid ``h`` (rows y, columns x)."""
    n = h.shape[0]
    for k in range(len(cx)):
        R = 0.5 * diam[k]
        d, rim = 0.2 * diam[k], 0.04 * diam[k]
        w = 1.5 * R
        i0, i1 = max(0, int((cx[k] - w - x0) / cell)), min(n - 1, int((cx[k] + w - x0) / cell) + 1)
        j0, j1 = max(0, int((cy[k] - w - x0) / cell)), min(n - 1, int((cy[k] + w - x0) / cell) + 1)
        for j in range(j0, j1 + 1):
            y = x0 + j * cell - cy[k]
            for i in range(i0, i1 + 1):
                x = x0 + i * cell - cx[k]
                r = math.sqrt(x * x + y * y)
                if r < R:
                    h[j, i] += d * ((r / R) ** 2 - 1.0) + rim
                elif r < w:
                    fade = 1.0 - ((r - R) / (w - R)) ** 2
                    h[j, i] += rim * (R / r) ** 3 * fade * fade


@numba.njit(cache=True)
def stamp_boulders(h, alb, x0, cell, cx, cy, a, b, c, theta, bury, factor):  # pragma: no cover - numba
    """Raise ``h`` to the tops of half-ellipsoid boulders and set their albedo factor in ``alb``."""
    n = h.shape[0]
    for k in range(len(cx)):
        jc = min(max(int(round((cy[k] - x0) / cell)), 0), n - 1)
        ic = min(max(int(round((cx[k] - x0) / cell)), 0), n - 1)
        z0 = h[jc, ic] - bury[k] * c[k]
        ct, st = math.cos(theta[k]), math.sin(theta[k])
        w = a[k]
        i0, i1 = max(0, int((cx[k] - w - x0) / cell)), min(n - 1, int((cx[k] + w - x0) / cell) + 1)
        j0, j1 = max(0, int((cy[k] - w - x0) / cell)), min(n - 1, int((cy[k] + w - x0) / cell) + 1)
        for j in range(j0, j1 + 1):
            y = x0 + j * cell - cy[k]
            for i in range(i0, i1 + 1):
                x = x0 + i * cell - cx[k]
                u, v = ct * x + st * y, -st * x + ct * y
                q = (u / a[k]) ** 2 + (v / b[k]) ** 2
                if q < 1.0:
                    top = z0 + c[k] * math.sqrt(1.0 - q)
                    if top > h[j, i]:
                        h[j, i] = top
                        alb[j, i] = factor[k]


@numba.njit(cache=True)
def rasterize_facets(tri, val, x0, cell, n, out_h, out_v):  # pragma: no cover - numba
    """Top-most height and interpolated value of triangles ``tri`` (F, 3, 3) (site x, y, h) at the
    grid points (x0 + i·cell, x0 + j·cell); front-facing (+h) triangles only. NaN where none."""
    for f in range(tri.shape[0]):
        ax, ay, ah = tri[f, 0, 0], tri[f, 0, 1], tri[f, 0, 2]
        bx, by, bh = tri[f, 1, 0], tri[f, 1, 1], tri[f, 1, 2]
        qx, qy, qh = tri[f, 2, 0], tri[f, 2, 1], tri[f, 2, 2]
        det = (bx - ax) * (qy - ay) - (qx - ax) * (by - ay)
        if det <= 0.0:
            continue
        i0 = max(0, int(math.ceil((min(ax, bx, qx) - x0) / cell)))
        i1 = min(n - 1, int(math.floor((max(ax, bx, qx) - x0) / cell)))
        j0 = max(0, int(math.ceil((min(ay, by, qy) - x0) / cell)))
        j1 = min(n - 1, int(math.floor((max(ay, by, qy) - x0) / cell)))
        for j in range(j0, j1 + 1):
            y = x0 + j * cell
            for i in range(i0, i1 + 1):
                x = x0 + i * cell
                wb = ((x - ax) * (qy - ay) - (qx - ax) * (y - ay)) / det
                wc = ((bx - ax) * (y - ay) - (x - ax) * (by - ay)) / det
                wa = 1.0 - wb - wc
                if wa < -1e-9 or wb < -1e-9 or wc < -1e-9:
                    continue
                hh = wa * ah + wb * bh + wc * qh
                if math.isnan(out_h[j, i]) or hh > out_h[j, i]:
                    out_h[j, i] = hh
                    out_v[j, i] = wa * val[f, 0] + wb * val[f, 1] + wc * val[f, 2]


def grid_faces(n: int) -> np.ndarray:
    """(2(n−1)², 3) int32 faces of an n × n vertex grid (index j·n + i), counter-clockwise seen
    from +z when columns run along +x and rows along +y: (v00, v01, v11) and (v00, v11, v10)."""
    return rect_faces(n, n)


def rect_faces(ny: int, nx: int) -> np.ndarray:
    """Faces of an ny × nx vertex grid (index j·nx + i), in the convention of :func:`grid_faces`."""
    j, i = np.meshgrid(np.arange(ny - 1, dtype=np.int32), np.arange(nx - 1, dtype=np.int32), indexing="ij")
    v00 = (j * nx + i).ravel()
    v01, v10, v11 = v00 + 1, v00 + nx, v00 + nx + 1
    out = np.empty((2 * len(v00), 3), np.int32)
    out[0::2] = np.column_stack([v00, v01, v11])
    out[1::2] = np.column_stack([v00, v11, v10])
    return out


def grid_interp(grid: np.ndarray, x0: float, cell: float, x, y) -> np.ndarray:
    """Value of the triangulated grid (see :func:`grid_faces`) at (x, y): exact on its facets.
    Points outside the grid are clamped to its border."""
    n = grid.shape[0]
    u = np.clip((np.asarray(x, float) - x0) / cell, 0, n - 1)
    v = np.clip((np.asarray(y, float) - x0) / cell, 0, n - 1)
    i = np.minimum(np.floor(u).astype(np.int64), n - 2)
    j = np.minimum(np.floor(v).astype(np.int64), n - 2)
    fx, fy = u - i, v - j
    h00, h01 = grid[j, i].astype(float), grid[j, i + 1].astype(float)
    h10, h11 = grid[j + 1, i].astype(float), grid[j + 1, i + 1].astype(float)
    lower = fx >= fy  # triangle (v00, v01, v11)
    return np.where(lower, h00 + fx * (h01 - h00) + fy * (h11 - h01), h00 + fy * (h10 - h00) + fx * (h11 - h10))
