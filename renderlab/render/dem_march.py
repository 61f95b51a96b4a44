"""Exact ray casting of a height grid (DEM) by a march over a max-height pyramid: no BVH, nothing built per frame.

Description
-----------
The DEM is a regular grid of heights h[j, i] (row j along site +y, column i along +x) at x = x0 + i·c,
y = y0 + j·c, each cell split by its diagonal v00–v11 into the two triangles of
:func:`renderlab.worlds.ev5.terrain.grid_faces`: 0 = (v00, v01, v11) where fx ≥ fy, 1 = (v00, v11, v10) where
fy ≥ fx (fx, fy the position inside the cell in cell units). Its **max-height pyramid** (:func:`build_pyramid`,
numpy, once per DEM) holds at level 0 the maximum of each cell's four corner heights and at level L the maximum of
the 2×2 nodes below (a "maximum mipmap": A. Tevs, I. Ihrke, H.-P. Seidel, "Maximum mipmaps for fast, accurate,
and scalable dynamic height field rendering", I3D 2008, doi:10.1145/1342250.1342279). Every triangle of a node's
footprint lies below the node's maximum, so a ray whose height stays above it over the footprint misses them all.

:class:`DemMarch` traces rays (Dr.Jit, one symbolic ``dr.while_loop``; LLVM or CUDA arrays) in the grid's frame.
The ray is clipped to the DEM's bounding box and starts at the pyramid's top node; per iteration, with the node's
footprint entered at t and left at t_exit (ray–box slab test, Kay & Kajiya 1986)::

    z_lo = min(z(t), z(t_exit))      (the ray is straight: its lowest point over the footprint)
    z_lo ≤ max + slack, level > 0  → advance t to where z(t) falls to max (descending rays), then descend
                                     into the descendant (``descent_levels`` down) containing the ray at t
    z_lo ≤ max + slack, level 0    → exact test of the cell's two triangles; the nearer hit ends the march
    otherwise (or no hit)          → step to the neighbour across the exit face; ascend one level when it has
                                     another parent

Nodes are visited in increasing t, so the first cell with a hit holds the nearest hit. The triangle test
intersects the ray with the triangle's plane z = h00 + fx·a + fy·b (t = (h00 + fx0·a + fy0·b − z0) /
(dz − dfx·a − dfy·b), a, b its slopes per cell) and accepts the hit where (fx, fy) lies inside the triangle, with a
tolerance of ``edge_eps`` cells so that neighbouring triangles overlap by a hair: no ray slips through a shared edge
(the hit may then be reported in either neighbour: an exact-edge tie). Barycentrics follow Mitsuba's convention
p = (1 − b1 − b2)·v0 + b1·v1 + b2·v2 for the triangle's vertices in ``grid_faces`` order: triangle 0 b1 = fx − fy,
b2 = fy; triangle 1 b1 = fx, b2 = fy − fx. Both sides of a triangle are hit (as Embree does).

Tuning
------
``slack_m`` (default 1e-4 m): added to each node maximum so that float32 rounding of z(t) cannot skip a node (costs
a few extra descents). ``edge_eps`` (default 1e-5 cells): the triangle overlap above. ``max_iterations``: a
safety cap on the loop (a ray that reaches it is reported as a miss and counted in ``iterations``).
``descent_levels`` (default 2): a node the ray may meet is entered ``descent_levels`` levels down at once, at the
descendant holding the ray where its height falls to the node's maximum (exact either way: every node's maximum
bounds its own triangles; it trades the intermediate level's pruning for fewer iterations). On the full EV5 site,
2 instead of 1 takes the mean nodes per camera ray at 1000 / 171 / 5 m from 14.0 / 11.0 / 6.8 to 10.2 / 7.2 / 4.2
and the Mitsuba backend's 1024², 16 spp render of those frames to 0.98 / 0.93 / 0.92× of its time with 1, timed
next to it (``benchmarks/bench_dem_descent.py --repeats 5``, medians, load 2.1 → 1.9); 3 and 4 were no faster.

Use
---
``pyr = build_pyramid(site.heights_m, site.x0_m, site.cell_m)`` once per DEM; ``march = DemMarch(pyr)``;
``hit = march.intersect(o, d, t_max)`` with o, d Dr.Jit 3-vectors in the grid's frame (site frame: x, y, height)
→ :class:`MarchHit`; ``march.occluded(o, d, t_max)`` for shadow rays (any hit). ``tests/test_dem_march.py``
compares it with the lab's float64 ray oracle; ``benchmarks/bench_dem_march.py`` times it on the EV5 site.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from renderlab.errors import UserError


@dataclass(frozen=True)
class HeightPyramid:
    """A DEM and its max-height pyramid (module docstring), float32.

    Level L holds ``rows[L]`` × ``cols[L]`` nodes, node (J, I) covering cells [I·2^L, (I+1)·2^L) × [J·2^L, (J+1)·2^L)
    (nodes past the grid's edge cover fewer cells). ``maxima`` stores the levels top first, each as a square of side
    2^(P − L) (P = the top level; −inf beyond ``rows[L]`` × ``cols[L]``), row-major: node (J, I) of level L is at
    (4^(P − L) − 1)/3 + J·2^(P − L) + I, arithmetic that the march evaluates instead of a table look-up
    (:meth:`level` gives a level's nodes).
    """

    heights: np.ndarray  # (ny, nx) float32 vertex heights
    x0_m: float
    y0_m: float
    cell_m: float
    maxima: np.ndarray  # float32, all levels (padded squares, top first)
    rows: np.ndarray  # (levels,) int64
    cols: np.ndarray  # (levels,) int64

    @property
    def levels(self) -> int:
        return len(self.rows)

    @property
    def h_min(self) -> float:
        return float(self.heights.min())

    @property
    def h_max(self) -> float:
        return float(self.maxima[0])

    def level(self, L: int) -> np.ndarray:
        """The (rows[L], cols[L]) node maxima of level L."""
        return _padded_level(self.maxima, self.levels - 1, L)[:self.rows[L], :self.cols[L]]


def _padded_level(maxima: np.ndarray, top: int, L: int) -> np.ndarray:
    """The padded square of level L in ``maxima`` (a view): side 2^(top − L), from (4^(top − L) − 1)/3."""
    side = 1 << (top - L)
    o = (side * side - 1) // 3
    return maxima[o:o + side * side].reshape(side, side)


def build_pyramid(heights, x0_m: float, cell_m: float, y0_m: float | None = None) -> HeightPyramid:
    """The max-height pyramid of the (ny, nx) vertex heights ``heights`` (module docstring).

    Parameters
    ----------
    heights : array (ny, nx)
        Heights at x = x0 + i·c (column i), y = y0 + j·c (row j); rounded to float32 (as the renderers do).
    x0_m, cell_m : float
    y0_m : float, optional
        Default ``x0_m`` (the site's square grid).
    """
    h = np.ascontiguousarray(heights, dtype=np.float32)
    if h.ndim != 2 or min(h.shape) < 2 or not np.all(np.isfinite(h)):
        raise UserError(f"DEM heights must be a finite (ny, nx) grid with ny, nx ≥ 2, got shape {h.shape}")
    if not cell_m > 0:
        raise UserError(f"DEM cell size must be > 0, got {cell_m!r}")
    level = np.maximum(np.maximum(h[:-1, :-1], h[:-1, 1:]), np.maximum(h[1:, :-1], h[1:, 1:]))
    out = [level]
    while max(level.shape) > 1:
        r, c = level.shape
        pad = np.full((r + r % 2, c + c % 2), -np.inf, np.float32)
        pad[:r, :c] = level
        level = np.maximum(np.maximum(pad[0::2, 0::2], pad[0::2, 1::2]), np.maximum(pad[1::2, 0::2], pad[1::2, 1::2]))
        out.append(level)
    top = len(out) - 1
    maxima = np.full((4 ** (top + 1) - 1) // 3, -np.inf, np.float32)
    for L, a in enumerate(out):
        _padded_level(maxima, top, L)[:a.shape[0], :a.shape[1]] = a
    return HeightPyramid(h, float(x0_m), float(x0_m if y0_m is None else y0_m), float(cell_m), maxima,
                         np.array([a.shape[0] for a in out], np.int64), np.array([a.shape[1] for a in out], np.int64))


@dataclass
class MarchHit:
    """Per ray: ``valid`` (hit), ``t`` (inf where missed), cell ``i`` (column) and ``j`` (row), ``tri`` (0 or 1 as
    in ``grid_faces``: face index 2·(j·(nx−1) + i) + tri), barycentrics ``b1``, ``b2`` and the hit point ``p`` (grid
    frame), and the loop ``iterations`` the ray took (nodes visited)."""

    valid: object
    t: object
    i: object
    j: object
    tri: object
    b1: object
    b2: object
    p: object
    iterations: object


def jit_module(variant: str | None = None):
    """The Dr.Jit array namespace (``drjit.llvm.ad`` or ``drjit.cuda.ad``) of a Mitsuba variant name."""
    if variant is not None and variant.startswith("cuda"):
        import drjit.cuda.ad as jit
    else:
        import drjit.llvm.ad as jit
    return jit


class DemMarch:
    """Ray caster of one DEM (module docstring): the pyramid is uploaded once.

    Parameters
    ----------
    pyramid : HeightPyramid
    jit : module, optional
        Dr.Jit array namespace (``drjit.llvm.ad`` default; :func:`jit_module`).
    slack_m, edge_eps : float
        See Tuning.
    max_iterations : int, optional
        Default 8·(nx + ny) + 16·levels.
    descent_levels : int
        Levels a descent goes down at once (default 2: into the grandchild holding the ray; see Tuning).
    """

    def __init__(self, pyramid: HeightPyramid, jit=None, slack_m: float = 1e-4, edge_eps: float = 1e-5,
                 max_iterations: int | None = None, descent_levels: int = 2):
        import drjit as dr

        self.dr, self.jit = dr, jit if jit is not None else jit_module()
        self.pyr = pyramid
        ny, nx = pyramid.heights.shape
        self.nx, self.ny = nx, ny
        self.top = pyramid.levels - 1
        self.slack, self.edge_eps = float(slack_m), float(edge_eps)
        self.descent = int(descent_levels)
        if self.descent < 1:
            raise UserError(f"DEM march descent_levels must be ≥ 1, got {descent_levels!r}")
        self.max_iterations = int(max_iterations or 8 * (nx + ny) + 16 * pyramid.levels)
        J = self.jit
        self.heights = J.Float(pyramid.heights.ravel())
        self.maxima = J.Float(pyramid.maxima)
        dr.eval(self.heights, self.maxima)

    # ------------------------------------------------------------------ public
    def intersect(self, o, d, t_max=None, t_min: float = 0.0) -> MarchHit:
        """Nearest hit of rays ``o + t·d`` (t_min < t ≤ t_max; ``t_max`` default inf) with the DEM's triangles."""
        return self._march(o, d, t_max, t_min, nearest=True)

    def occluded(self, o, d, t_max=None, t_min: float = 0.0):
        """Bool per ray: some DEM triangle is hit with t_min < t ≤ t_max (shadow rays)."""
        return self._march(o, d, t_max, t_min, nearest=False).valid

    # ------------------------------------------------------------------ kernel
    def _setup(self, o, d, t_max, t_min):
        """Grid-unit rays (u = (x − x0)/c, v = (y − y0)/c, z in m; t unchanged) and their [t0, t1] in the DEM's box."""
        dr, J, p = self.dr, self.jit, self.pyr
        inv_c = 1.0 / p.cell_m
        ou, ov, oz = (J.Float(o[0]) - p.x0_m) * inv_c, (J.Float(o[1]) - p.y0_m) * inv_c, J.Float(o[2])
        du, dv, dz = J.Float(d[0]) * inv_c, J.Float(d[1]) * inv_c, J.Float(d[2])
        t0 = J.Float(t_min)
        t1 = J.Float(dr.inf) if t_max is None else J.Float(t_max)
        for org, dirn, lo, hi in ((ou, du, 0.0, self.nx - 1.0), (ov, dv, 0.0, self.ny - 1.0),
                                  (oz, dz, p.h_min - self.slack, p.h_max + self.slack)):
            inv = dr.rcp(dirn)
            ta, tb = (lo - org) * inv, (hi - org) * inv
            inside = (org >= lo) & (org <= hi)
            t0 = dr.select(dirn == 0, t0, dr.maximum(t0, dr.minimum(ta, tb)))
            t1 = dr.select(dirn == 0, dr.select(inside, t1, -dr.inf), dr.minimum(t1, dr.maximum(ta, tb)))
        ok = (t0 <= t1) & dr.isfinite(t0) & dr.isfinite(du) & dr.isfinite(dv) & dr.isfinite(dz)
        return (ou, ov, oz, du, dv, dz, dr.rcp(du), dr.rcp(dv)), t0, t1, ok

    def _start(self, ray, t0, t1, t_min):
        """Start node (I, J, level) of each ray: the level whose nodes span the ray's horizontal extent inside the
        DEM's box (level 0 for a ray that starts inside it, e.g. a shadow ray), the node holding the ray at t0."""
        dr, J = self.dr, self.jit
        ou, ov, oz, du, dv, dz = ray[:6]
        ext = dr.maximum(dr.abs(du), dr.abs(dv)) * dr.minimum(t1 - t0, 1e30)
        L = J.Int32(dr.clip(dr.ceil(dr.log2(dr.maximum(ext, 1.0))), 0, self.top))
        p0 = (ou + t0 * du, ov + t0 * dv, oz + t0 * dz)
        inside = (p0[2] < self.pyr.h_max) & (p0[0] > 0) & (p0[0] < self.nx - 1) & (p0[1] > 0) & (p0[1] < self.ny - 1)
        L = dr.select(inside & (t0 == t_min), 0, L)
        I = dr.clip(J.Int32(dr.floor(p0[0])), 0, self.nx - 2) >> L
        J_ = dr.clip(J.Int32(dr.floor(p0[1])), 0, self.ny - 2) >> L
        return I, J_, L

    @staticmethod
    def _count(n_vertices: int, L):
        """Nodes per row (or column) at level L of a grid of ``n_vertices`` vertices: ceil((n − 1) / 2^L)."""
        return ((L * 0 + (n_vertices - 2)) >> L) + 1

    def _node_exit(self, ray, I, J_, L, t_end):
        """Exit t of node (I, J_) at level L and whether it leaves across the u face (else the v face)."""
        dr, J = self.dr, self.jit
        ou, ov, _, du, dv, _, iu, iv = ray
        bu = J.Float(dr.select(du > 0, I + 1, I) << L)  # the face the ray leaves across
        bv = J.Float(dr.select(dv > 0, J_ + 1, J_) << L)
        tu = dr.select(du == 0, dr.inf, (bu - ou) * iu)
        tv = dr.select(dv == 0, dr.inf, (bv - ov) * iv)
        return dr.minimum(dr.minimum(tu, tv), t_end), tu <= tv, dr.minimum(tu, tv) >= t_end

    def _cell_hit(self, ray, I, J_, t_lo, t_hi, active):
        """Nearer hit of the two triangles of cell (I, J_) with t in [t_lo, t_hi]: (hit, t, tri, fx, fy)."""
        dr, J = self.dr, self.jit
        ou, ov, oz, du, dv, dz = ray[:6]
        k = J_ * self.nx + I
        h00 = dr.gather(J.Float, self.heights, k, active)
        h01 = dr.gather(J.Float, self.heights, k + 1, active)
        h10 = dr.gather(J.Float, self.heights, k + self.nx, active)
        h11 = dr.gather(J.Float, self.heights, k + self.nx + 1, active)
        au, av = ou - J.Float(I), ov - J.Float(J_)
        e = self.edge_eps
        best_t, best_tri = J.Float(dr.inf), J.Int32(0)
        best_fx, best_fy = J.Float(0.0), J.Float(0.0)
        for tri, (a, b) in enumerate(((h01 - h00, h11 - h01), (h11 - h10, h10 - h00))):
            t = (h00 + au * a + av * b - oz) / (dz - du * a - dv * b)
            fx, fy = au + t * du, av + t * dv
            inside = (fx - fy >= -e) if tri == 0 else (fy - fx >= -e)
            inside &= (fx >= -e) & (fx <= 1 + e) & (fy >= -e) & (fy <= 1 + e)
            ok = active & inside & (t >= t_lo) & (t <= t_hi) & (t < best_t)
            best_t = dr.select(ok, t, best_t)
            best_tri = dr.select(ok, tri, best_tri)
            best_fx, best_fy = dr.select(ok, fx, best_fx), dr.select(ok, fy, best_fy)
        return dr.isfinite(best_t), best_t, best_tri, best_fx, best_fy

    def _descendant(self, ray, I, J_, L, t):
        """The node ``descent_levels`` (at most L) below node (I, J_) at level L that holds the ray at t: (I, J, level)
        (clamped into the node; a wrong pick on a boundary has an empty interval and steps into its sibling)."""
        dr, J = self.dr, self.jit
        ou, ov, _, du, dv = ray[:5]
        k = dr.minimum(L, self.descent)
        c = L - k
        cu = J.Int32(dr.floor(ou + t * du)) >> c
        cv = J.Int32(dr.floor(ov + t * dv)) >> c
        cu = dr.clip(cu, I << k, dr.minimum(((I + 1) << k) - 1, self._count(self.nx, c) - 1))
        cv = dr.clip(cv, J_ << k, dr.minimum(((J_ + 1) << k) - 1, self._count(self.ny, c) - 1))
        return cu, cv, c

    def _march(self, o, d, t_max, t_min, nearest: bool) -> MarchHit:
        dr, J = self.dr, self.jit
        ray, t0, t1, ok = self._setup(o, d, t_max, t_min)
        I0, J0, L0 = self._start(ray, t0, t1, t_min)
        # rebase: the ray starts at its entry into the DEM's box (t0 = 0 there): the heights, the cell-relative
        # positions and t stay small numbers, so float32 rounding stays far below edge_eps (a ray at 170 m would
        # otherwise carry 1e-4 cells of error and slip through edges)
        t0 = dr.select(ok, t0, 0.0)
        ou, ov, oz, du, dv, dz = ray[:6]
        ou, ov, oz = ou + t0 * du, ov + t0 * dv, oz + t0 * dz
        ray = (ou, ov, oz, du, dv, dz) + tuple(ray[6:])
        t_lo = J.Float(t_min) - t0
        t_hi = (J.Float(dr.inf) if t_max is None else J.Float(t_max)) - t0
        t1 = t1 - t0
        zero = dr.zeros(J.Int32, dr.width(ok))  # per-ray integers (the state has the rays' width)
        # the nearest hit carries its t, triangle and position in the cell; a shadow ray (any hit) only its flag:
        # a smaller loop state (fewer registers live across the loop inside the renderer's kernel)
        extra = (J.Float(dr.inf), zero, J.Float(0.0), J.Float(0.0)) if nearest else ()
        state = (ok, J.Bool(False), J.Float(0.0) + J.Float(zero), I0 + zero, J0 + zero, L0 + zero, zero, *extra)

        def cond(active, *_):
            return active

        def body(active, hit, t, I, J_, L, it, *extra):
            t_exit, across_u, last = self._node_exit(ray, I, J_, L, t1)
            z_lo = dr.minimum(oz + t * dz, oz + t_exit * dz)
            k = self.top - L  # the node's index in the padded layout (HeightPyramid): (4^k − 1)/3 + J·2^k + I
            m = dr.gather(J.Float, self.maxima, (0x55555555 & ((J.Int32(1) << (k + k)) - 1)) + (J_ << k) + I, active)
            can = active & (z_lo <= m + self.slack)
            leaf = can & (L == 0)
            zf, zi = J.Float(0.0) * t, J.Int32(0) * I
            # the triangle tests as a branch: a SIMD packet with no lane at a reached leaf skips them (1.5x faster)
            if nearest:
                found, th, trh, fxh, fyh = dr.if_stmt(
                    (I, J_, leaf), leaf, lambda I, J_, leaf: self._cell_hit(ray, I, J_, t_lo, t_hi, leaf),
                    lambda I, J_, leaf: (leaf & False, zf + dr.inf, zi, zf, zf))
                extra = tuple(dr.select(found, new, old) for new, old in zip((th, trh, fxh, fyh), extra))
            else:
                found = dr.if_stmt((I, J_, leaf), leaf,
                                   lambda I, J_, leaf: self._cell_hit(ray, I, J_, t_lo, t_hi, leaf)[0],
                                   lambda I, J_, leaf: leaf & False)
            hit = hit | found
            down = can & (L > 0)
            # a descending ray cannot meet the node's triangles before its height falls to the node's maximum: the
            # descent starts there (t_top ≤ t_exit, since z(t_exit) ≤ max + slack; fewer children visited)
            t_top = dr.select(dz < 0, (m + self.slack - oz) / dz, t)
            t = dr.select(down, dr.clip(t_top, t, t_exit), t)
            cu, cv, c = self._descendant(ray, I, J_, L, t)
            step = active & ~found & ~down
            su = dr.select(du > 0, J.Int32(1), J.Int32(-1))
            sv = dr.select(dv > 0, J.Int32(1), J.Int32(-1))
            In = dr.select(step & across_u, I + su, I)
            Jn = dr.select(step & ~across_u, J_ + sv, J_)
            up = step & (L < self.top) & (((In >> 1) != (I >> 1)) | ((Jn >> 1) != (J_ >> 1)))
            In, Jn = dr.select(up, In >> 1, In), dr.select(up, Jn >> 1, Jn)
            Ln = dr.select(up, L + 1, L)
            In, Jn, Ln = dr.select(down, cu, In), dr.select(down, cv, Jn), dr.select(down, c, Ln)
            t = dr.select(step, dr.maximum(t, t_exit), t)
            outside = (In < 0) | (Jn < 0) | (In >= self._count(self.nx, Ln)) \
                | (Jn >= self._count(self.ny, Ln))
            it = it + J.Int32(active)
            active = active & ~found & ~(step & (last | outside)) & (it < self.max_iterations)
            return active, hit, t, In, Jn, Ln, it, *extra

        labels = ("active", "hit", "t", "I", "J", "L", "it") + (("t_hit", "tri", "fx", "fy") if nearest else ())
        _, hit, _, I, J_, _, it, *extra = dr.while_loop(state, cond, body, labels=labels, label="dem_march")
        if not nearest:  # where a shadow ray is blocked, not by what
            return MarchHit(hit, None, I, J_, None, None, None, None, it)
        t_rel, tri, fx, fy = extra
        t_hit = dr.select(hit, t0 + t_rel, dr.inf)
        b1 = dr.select(tri == 0, fx - fy, fx)
        b2 = dr.select(tri == 0, fy, fy - fx)
        p = self.pyr
        pos = (p.x0_m + (J.Float(I) + fx) * p.cell_m, p.y0_m + (J.Float(J_) + fy) * p.cell_m,
               oz + t_rel * dz)
        return MarchHit(hit, t_hit, dr.select(hit, I, -1), dr.select(hit, J_, -1), dr.select(hit, tri, -1),
                        b1, b2, pos, it)
