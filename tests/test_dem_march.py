"""The DEM ray march (:mod:`renderlab.render.dem_march`) against the lab's float64 ray oracle.

A seeded 64² -cell DEM (random-walk relief with steps and spikes, 0.25 m cells) and 4 800 seeded rays of six kinds
(steep, oblique, grazing, axis-parallel and vertical, from the surface upward, cut by t_max); the oracle is
:func:`renderlab.render.ray_oracle._moller_trumbore` (float64, Möller & Trumbore 1997) over all 8 192 triangles of
``terrain.grid_faces``, with the DEM and the rays rounded to float32 (the geometry the kernel sees).
"""

from __future__ import annotations

import numpy as np
import pytest

from renderlab.errors import UserError
from renderlab.render.ray_oracle import _moller_trumbore
from renderlab.worlds.ev5.terrain import grid_faces

N, CELL, X0 = 65, 0.25, -8.0


def _dem(rng):
    h = np.cumsum(np.cumsum(rng.normal(0.0, 0.04, (N, N)), 0), 1)
    h += 0.6 * (rng.random((N, N)) < 0.01)  # isolated spikes: one-vertex "boulders"
    h[20:30, 40:45] += 0.8  # a step-sided block
    return (h - h.mean()).astype(np.float32).astype(np.float64)


def _rays(rng, h):
    """(o, d, t_max, t_min) float64 (rounded to float32) of six kinds, 800 each."""
    k, lo, hi = 800, X0, X0 + (N - 1) * CELL
    kinds = []
    o = np.c_[rng.uniform(lo - 4, hi + 4, (k, 2)), rng.uniform(5, 40, k)]  # steep, from above
    kinds.append((o, np.c_[rng.uniform(lo, hi, (k, 2)), rng.uniform(-2, 2, k)] - o))
    o = np.c_[rng.uniform(lo - 20, hi + 20, (k, 2)), rng.uniform(0, 6, k)]  # oblique
    kinds.append((o, np.c_[rng.uniform(lo, hi, (k, 2)), rng.uniform(-2, 1, k)] - o))
    az = rng.uniform(0, 2 * np.pi, k)  # grazing: nearly horizontal through the relief
    o = np.c_[-20 * np.cos(az), -20 * np.sin(az), rng.uniform(h.min(), h.max(), k)]
    kinds.append((o, np.c_[np.cos(az), np.sin(az), rng.uniform(-0.03, 0.03, k)]))
    o = np.c_[rng.uniform(lo, hi, (k, 2)), rng.uniform(h.min(), h.max() + 1, k)]  # axis-parallel and vertical
    d = np.zeros((k, 3))
    axis = rng.integers(0, 3, k)
    d[np.arange(k), axis] = rng.choice([-1.0, 1.0], k)
    d[axis == 2, 2] = -1.0
    for a in (0, 1):  # horizontal rays start outside the grid, vertical ones above it
        o[axis == a, a] = np.where(d[axis == a, a] > 0, lo - 1.0, hi + 1.0)
    o[axis == 2, 2] = h.max() + 1.0
    kinds.append((o, d))
    xy = rng.uniform(lo + 0.1, hi - 0.1, (k, 2))  # from the surface upward (shadow rays)
    from renderlab.worlds.ev5.terrain import grid_interp

    o = np.c_[xy, grid_interp(h, X0, CELL, xy[:, 0], xy[:, 1]) + 1e-3]
    el = rng.uniform(0.02, 0.6, k)
    az = rng.uniform(0, 2 * np.pi, k)
    kinds.append((o, np.c_[np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)]))
    o = np.c_[rng.uniform(lo - 4, hi + 4, (k, 2)), rng.uniform(3, 10, k)]  # cut by t_max
    kinds.append((o, np.c_[rng.uniform(lo, hi, (k, 2)), rng.uniform(-2, 2, k)] - o))
    o = np.concatenate([a for a, _ in kinds])
    d = np.concatenate([b for _, b in kinds])
    d /= np.linalg.norm(d, axis=1)[:, None]
    t_max = np.full(len(o), np.inf)
    t_max[-k:] = rng.uniform(1, 15, k)
    f32 = lambda a: a.astype(np.float32).astype(np.float64)  # noqa: E731
    return f32(o), f32(d), t_max


def _oracle(h, o, d, t_max, t_min=0.0):
    """Float64 nearest hit over all triangles: (t (inf = miss), face, u, v)."""
    X, Y = np.meshgrid(X0 + np.arange(N) * CELL, X0 + np.arange(N) * CELL)
    T = np.stack([X, Y, h], -1).reshape(-1, 3)[grid_faces(N)]
    t_best, face = np.full(len(o), np.inf), np.full(len(o), -1)
    ub, vb = np.zeros(len(o)), np.zeros(len(o))
    for a in range(0, len(o), 32):
        t, u, v = _moller_trumbore(o[a:a + 32], d[a:a + 32], T, t_min)
        t = np.where(t <= t_max[a:a + 32, None], t, np.inf)
        k = np.argmin(t, 1)
        r = np.arange(len(k))
        t_best[a:a + 32], face[a:a + 32], ub[a:a + 32], vb[a:a + 32] = t[r, k], k, u[r, k], v[r, k]
    face[~np.isfinite(t_best)] = -1
    return t_best, face, ub, vb


@pytest.fixture(scope="module")
def case():
    from renderlab.render.dem_march import DemMarch, build_pyramid, jit_module
    from renderlab.render.variant import init_mitsuba

    mi = init_mitsuba("llvm_ad_rgb")
    rng = np.random.default_rng(20261207)
    h = _dem(rng)
    o, d, t_max = _rays(rng, h)
    J = jit_module(mi.variant())
    march = DemMarch(build_pyramid(h, X0, CELL), jit=J)
    vec = lambda a: J.Array3f(np.ascontiguousarray(a.T, np.float32))  # noqa: E731
    return march, h, o, d, t_max, vec, J


def test_pyramid_is_the_block_maximum_of_the_cells():
    from renderlab.render.dem_march import build_pyramid

    h = np.random.default_rng(3).normal(size=(37, 21))  # odd, non-square: partial nodes at every level
    p = build_pyramid(h, 0.0, 1.0)
    h32 = h.astype(np.float32)
    for level in range(p.levels):
        s = 2 ** level
        nodes = p.level(level)
        k = p.levels - 1 - level  # the march's index arithmetic: (4^k − 1)/3 + J·2^k + I; −inf past the grid
        padded = p.maxima[(4 ** k - 1) // 3:(4 ** k - 1) // 3 + 4 ** k].reshape(2 ** k, 2 ** k)
        assert np.array_equal(padded[:p.rows[level], :p.cols[level]], nodes)
        assert np.all(padded[p.rows[level]:] == -np.inf) and np.all(padded[:, p.cols[level]:] == -np.inf)
        for J, I in [(0, 0), (p.rows[level] - 1, p.cols[level] - 1), (p.rows[level] // 2, 0)]:
            block = h32[J * s:(J + 1) * s + 1, I * s:(I + 1) * s + 1]  # vertices of the node's cells
            assert nodes[J, I] == block.max()
    assert p.levels == 7 and p.h_max == h32.max() and (p.rows[-1], p.cols[-1]) == (1, 1)


def test_bad_grid_is_a_user_error():
    from renderlab.render.dem_march import build_pyramid

    with pytest.raises(UserError, match="DEM heights"):
        build_pyramid(np.zeros((1, 5)), 0.0, 1.0)
    with pytest.raises(UserError, match="cell size"):
        build_pyramid(np.zeros((3, 3)), 0.0, 0.0)


def test_march_equals_the_float64_oracle(case):
    march, h, o, d, t_max, vec, J = case
    hit = march.intersect(vec(o), vec(d), J.Float(t_max.astype(np.float32)))
    valid, t = np.array(hit.valid), np.array(hit.t, np.float64)
    face = 2 * (np.array(hit.j) * (N - 1) + np.array(hit.i)) + np.array(hit.tri)
    t_ref, f_ref, u_ref, v_ref = _oracle(h, o, d, t_max)
    ref = np.isfinite(t_ref)
    assert 2000 < ref.sum() < len(o) - 500  # both hits and misses in every test
    # hit/miss: identical except where the oracle's hit lies on a triangle edge (|barycentric| < 1e-5: a tie)
    edge = np.minimum(np.minimum(u_ref, v_ref), 1 - u_ref - v_ref) < 1e-5
    assert np.all((valid == ref) | edge), np.nonzero((valid != ref) & ~edge)[0][:10]
    assert (valid != ref).sum() <= 2
    both = valid & ref
    assert np.abs(t[both] - t_ref[both]).max() <= 1e-4
    same = face[both] == f_ref[both]
    assert np.all(same | edge[both])
    # the hit point and barycentrics describe the reported triangle
    X = X0 + np.arange(N) * CELL
    V = np.stack(np.meshgrid(X, X) + [h], -1).reshape(-1, 3)[grid_faces(N)[face[both]]]
    b1, b2 = np.array(hit.b1)[both], np.array(hit.b2)[both]
    p_bary = (1 - b1 - b2)[:, None] * V[:, 0] + b1[:, None] * V[:, 1] + b2[:, None] * V[:, 2]
    p_ray = o[both] + t_ref[both, None] * d[both]
    assert np.abs(p_bary - p_ray).max() <= 2e-4
    assert np.abs(np.stack([np.array(c) for c in hit.p], 1)[both] - p_ray).max() <= 2e-4


def test_shadow_rays_equal_the_oracle(case):
    march, h, o, d, t_max, vec, J = case
    up = slice(4 * 800, 5 * 800)  # the rays leaving the surface
    occ = np.array(march.occluded(vec(o[up]), vec(d[up]), None, t_min=1e-4))
    t_ref, _, u_ref, v_ref = _oracle(h, o[up], d[up], np.full(800, np.inf), t_min=1e-4)
    ref = np.isfinite(t_ref)
    assert 50 < ref.sum() < 750
    edge = np.minimum(np.minimum(u_ref, v_ref), 1 - u_ref - v_ref) < 1e-5
    assert np.all((occ == ref) | edge) and (occ != ref).sum() <= 2


def test_rays_along_the_triangle_edges_do_not_slip_through(case):
    """Rays exactly along cell diagonals and anti-diagonals through grid vertices: every hit lies on an edge or a
    vertex; the march must find each one the oracle finds (watertight), at the same t (the triangle may differ)."""
    march, h, _, _, _, vec, J = case
    rng = np.random.default_rng(5)
    k = 400
    sx, sy = rng.choice([-1.0, 1.0], k), rng.choice([-1.0, 1.0], k)
    sy = np.where(rng.random(k) < 0.5, sx, sy)
    xy = X0 + rng.integers(0, N, (k, 2)) * CELL - 30 * CELL * np.c_[sx, sy]
    o = np.c_[xy, np.full(k, h.max() + 0.5)]
    d = np.c_[sx, sy, rng.uniform(-0.3, -0.01, k)]
    d /= np.linalg.norm(d, axis=1)[:, None]
    o, d = o.astype(np.float32).astype(np.float64), d.astype(np.float32).astype(np.float64)
    assert np.all(d[:, 0] == np.abs(d[:, 1]) * np.sign(d[:, 0]))  # still exactly diagonal after rounding
    hit = march.intersect(vec(o), vec(d))
    valid, t = np.array(hit.valid), np.array(hit.t, np.float64)
    t_ref = _oracle(h, o, d, np.full(k, np.inf))[0]
    ref = np.isfinite(t_ref)
    assert ref.sum() > 100 and np.array_equal(valid, ref)
    assert np.abs(t[ref] - t_ref[ref]).max() <= 1e-4


def test_far_rays_through_edges_of_a_fine_grid_do_not_slip_through():
    """The EV5 regime: 2 cm cells, the grid 30 m from the frame origin, rays from 170 m (float32 coordinates of
    ~1e4 cells), each aimed at a point *on* an edge of the surface (a vertex, a cell side or a diagonal): every ray
    must hit (the surface or something before it), no farther than its target, at the oracle's t where the float64
    oracle finds the hit (before the march re-based each ray at its entry into the box, 47 of these 2000 slipped
    through)."""
    from renderlab.render.dem_march import DemMarch, build_pyramid, jit_module
    from renderlab.render.variant import init_mitsuba
    from renderlab.worlds.ev5.terrain import grid_interp

    mi = init_mitsuba("llvm_ad_rgb")
    J = jit_module(mi.variant())
    rng = np.random.default_rng(11)
    cell, x0 = 0.02, 30.0
    h = np.cumsum(np.cumsum(rng.normal(0.0, 0.004, (N, N)), 0), 1).astype(np.float32).astype(np.float64)
    march = DemMarch(build_pyramid(h, x0, cell), jit=J)
    k = 2000
    ij = rng.integers(1, N - 2, (k, 2)).astype(float)
    f = rng.uniform(0, 1, k)
    kind = rng.integers(0, 4, k)  # vertex, side along x, side along y, diagonal
    fx = np.select([kind == 0, kind == 1, kind == 2], [0 * f, f, 0 * f], f)
    fy = np.select([kind == 0, kind == 1, kind == 2], [0 * f, 0 * f, f], f)
    xy = x0 + (ij + np.c_[fx, fy]) * cell
    target = np.c_[xy, grid_interp(h, x0, cell, xy[:, 0], xy[:, 1])]
    o = np.c_[xy + rng.uniform(-20.0, 20.0, (k, 2)), np.full(k, 170.0)]
    d = target - o
    dist = np.linalg.norm(d, axis=1)
    d /= dist[:, None]
    o, d = o.astype(np.float32).astype(np.float64), d.astype(np.float32).astype(np.float64)
    hit = march.intersect(J.Array3f(np.ascontiguousarray(o.T, np.float32)),
                          J.Array3f(np.ascontiguousarray(d.T, np.float32)))
    valid, t = np.array(hit.valid), np.array(hit.t, np.float64)
    X = x0 + np.arange(N) * cell
    T = np.stack(np.meshgrid(X, X) + [h], -1).reshape(-1, 3)[grid_faces(N)]
    t_ref = np.concatenate([_moller_trumbore(o[a:a + 32], d[a:a + 32], T, 0.0)[0].min(1) for a in range(0, k, 32)])
    ref = np.isfinite(t_ref)
    assert np.all(valid) and np.all(t <= dist + 1e-3)
    assert ref.sum() > 0.9 * k and np.abs(t[ref] - t_ref[ref]).max() <= 1e-4
    assert np.array(hit.iterations).max() < 64  # no ray walked on under the surface
