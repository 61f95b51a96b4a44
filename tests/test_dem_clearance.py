"""The clear square of a DEM (renderlab.render.dem_clearance) against a brute-force oracle: the static triangles
sampled densely and compared with the DEM's exact surface (terrain.grid_interp) point by point."""

from __future__ import annotations

import numpy as np
import pytest

from renderlab.render.dem_clearance import clear_square
from renderlab.worlds.ev5.terrain import grid_interp

N = 41  # vertices per side (40 × 40 cells)


def _dem(seed: int = 0) -> np.ndarray:
    """A smooth bumpy DEM (heights in m) on a 41 × 41 grid of 1-unit cells."""
    rng = np.random.default_rng(seed)
    u = np.arange(N, dtype=float)
    h = np.zeros((N, N))
    for _ in range(6):
        kx, ky, ph = rng.uniform(0.05, 0.4), rng.uniform(0.05, 0.4), rng.uniform(0, 2 * np.pi)
        h += rng.uniform(0.1, 0.5) * np.sin(kx * u[None, :] + ky * u[:, None] + ph)
    return h.astype(np.float32).astype(np.float64)


def _sheet(h: np.ndarray, step: float, depth: float) -> np.ndarray:
    """Triangles (T, 3, 3) of a sheet at ``step``-unit vertex spacing, hanging ``depth`` m under the DEM's minimum
    over the cells each of its triangles touches (so it is under the DEM everywhere), and reaching past its edges."""
    g = np.arange(-3.0, N + 2.0, step)
    U, V = np.meshgrid(g, g)
    tris = []
    for j in range(len(g) - 1):
        for i in range(len(g) - 1):
            a, b, c, d = (U[j, i], V[j, i]), (U[j, i + 1], V[j, i + 1]), (U[j + 1, i + 1], V[j + 1, i + 1]), \
                (U[j + 1, i], V[j + 1, i])
            lo = h[max(int(np.floor(a[1])), 0):min(int(np.floor(c[1])) + 1, N - 1) + 1,
                   max(int(np.floor(a[0])), 0):min(int(np.floor(c[0])) + 1, N - 1) + 1]
            z = (lo.min() if lo.size else 0.0) - depth
            for tri in ((a, b, c), (a, c, d)):
                tris.append([(p[0], p[1], z) for p in tri])
    return np.array(tris, float)


def _oracle_blocked(h: np.ndarray, tris: np.ndarray, margin: float, samples: int = 60) -> np.ndarray:
    """Cells where some densely sampled point of a triangle comes within ``margin`` of the DEM (or above it)."""
    blocked = np.zeros((N - 1, N - 1), bool)
    s = (np.arange(samples) + 0.5) / samples
    a, b = np.meshgrid(s, s)
    keep = a + b <= 1.0
    a, b = np.r_[a[keep], 0, 1, 0], np.r_[b[keep], 0, 0, 1]
    for t in tris:
        p = t[0] + a[:, None] * (t[1] - t[0]) + b[:, None] * (t[2] - t[0])
        inside = (p[:, 0] >= 0) & (p[:, 0] <= N - 1) & (p[:, 1] >= 0) & (p[:, 1] <= N - 1)
        p = p[inside]
        if not len(p):
            continue
        dem = grid_interp(h, 0.0, 1.0, p[:, 0], p[:, 1])
        hit = p[:, 2] >= dem - margin
        i = np.minimum(np.floor(p[hit, 0]).astype(int), N - 2)
        j = np.minimum(np.floor(p[hit, 1]).astype(int), N - 2)
        blocked[j, i] = True
    return blocked


def _oracle_r(blocked: np.ndarray) -> float:
    c = (N - 1) / 2.0
    jb, ib = np.nonzero(blocked)
    if not len(ib):
        return c
    du = np.maximum(np.maximum(ib - c, c - (ib + 1.0)), 0.0)
    dv = np.maximum(np.maximum(jb - c, c - (jb + 1.0)), 0.0)
    return float(np.maximum(du, dv).min())


def test_a_sheet_under_the_dem_leaves_the_whole_grid_clear():
    h = _dem()
    sq = clear_square(h, _sheet(h, 2.5, 0.05))
    assert sq.blocked_cells == 0 and sq.r == pytest.approx((N - 1) / 2) and (sq.u_c, sq.v_c) == (20.0, 20.0)


@pytest.mark.parametrize("spot", [(27.3, 22.6, 0.02), (14.2, 9.5, -0.0005), (5.5, 31.0, 0.3)])
def test_a_triangle_reaching_the_dem_blocks_its_cells_and_shrinks_the_square(spot):
    """A small triangle whose top vertex reaches ``dz`` m above the DEM (or within the 1 mm margin of it): the cells the
    oracle finds it reaching are all blocked, and the square stops at the nearest of them (to the oracle's r, or
    within one cell inside it: the bound is conservative over a cell)."""
    h = _dem(1)
    u, v, dz = spot
    top = grid_interp(h, 0.0, 1.0, np.array([u]), np.array([v]))[0] + dz
    spike = np.array([[[u - 0.7, v - 0.6, top - 0.5], [u + 0.8, v - 0.4, top - 0.5], [u, v, top]]])
    tris = np.concatenate([_sheet(h, 2.5, 0.05), spike])
    sq = clear_square(h, tris, margin_m=1e-3)
    oracle = _oracle_blocked(h, tris, 1e-3)
    assert oracle.any()
    r_oracle = _oracle_r(oracle)
    assert r_oracle - 1.0 <= sq.r <= r_oracle
    assert not sq.contains(u, v)  # the spike's top is outside the square
    assert sq.contains(sq.u_c + 0.9 * sq.r, sq.v_c - 0.9 * sq.r)


def test_a_box_over_the_site_blocks_the_cells_under_it():
    """A body floating over the site (a box's 12 triangles, as the renderer passes a non-mesh shape) blocks every cell
    under it, however high it floats."""
    h = _dem(2)
    lo, hi = np.array([18.2, 24.5, 30.0]), np.array([19.6, 26.1, 31.0])
    V = np.array([[(lo, hi)[(k >> a) & 1][a] for a in range(3)] for k in range(8)])
    F = np.array([[0, 1, 3], [0, 3, 2], [4, 5, 7], [4, 7, 6], [0, 1, 5], [0, 5, 4],
                  [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 3, 7], [1, 7, 5]])
    sq = clear_square(h, V[F])
    assert sq.blocked_cells == 2 * 3  # cells 18–19 × 24–26
    assert sq.r == pytest.approx(24.0 - 20.0)  # the nearest blocked cell starts at v = 24
    assert not sq.contains(19.0, 25.0)


def test_vertical_and_far_triangles():
    """A vertical triangle (no plane over (u, v)) blocks the cells it stands in when it reaches the DEM; triangles off
    the grid block nothing."""
    h = np.zeros((N, N))
    wall = np.array([[[10.5, 5.2, -1.0], [10.5, 7.8, -1.0], [10.5, 6.0, 0.5]]])
    off = np.array([[[-9.0, -9.0, 5.0], [-5.0, -9.0, 5.0], [-5.0, -4.0, 5.0]]])
    sq = clear_square(h, np.concatenate([wall, off]))
    assert sq.blocked_cells == 3 and sq.r == pytest.approx(20.0 - 8.0)
    low = wall.copy()
    low[0, :, 2] -= 0.6  # its top 1 cm under the DEM: clear
    assert clear_square(h, low).blocked_cells == 0
