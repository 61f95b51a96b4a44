"""Where a DEM hides everything else: the clear square of a marched site, over which the static scene needs no test.

Description
-----------
The DEM design (:mod:`renderlab.render.mitsuba_dem`) traces every ray twice: the DEM march and Embree on the static
scene (the global body, cut and lowered under the site). Over the site most of the second test is wasted: the global
facets there lie under the DEM, so no ray that reaches them from above can get past the DEM first. This module finds,
once per site, the region where that holds *numerically* (not by the site's construction), so the renderer may skip
the static scene there without changing any result:

* **blocked cells.** In the DEM's grid units (u = (x − x0)/c, v = (y − y0)/c, z in m) every static triangle whose
  (u, v) projection meets cell (i, j) bounds its own height over the cell by ``min(max vertex z, max of its plane at
  the cell's four corners)`` (a plane is linear, so its maximum over the cell square is at a corner; the vertical
  triangles whose plane is undefined keep the first bound). The DEM's two triangles over the cell lie above the
  minimum of its four corner heights. A cell is **blocked** when the bound is not at least ``margin_m`` under that
  minimum; a triangle meets the cell unless one of its edges' lines, or the cell's axes, separates them
  (separating-axis test).
* **the clear square** |u − u_c| < r, |v − v_c| < r about the grid's centre (u_c, v_c): r is the Chebyshev distance
  from the centre to the nearest blocked cell (or to the grid's edge). Every point strictly inside lies in an
  unblocked cell, so everything of the static scene inside the square's prism (infinite in z) lies at least
  ``margin_m`` under the DEM.

Hence, for a segment inside the prism that stays above the DEM (it does not cross the DEM's surface and starts above
it), the static scene cannot hit it: a camera ray from above the DEM to its first DEM hit, both ends in the square;
a shadow ray that the march found unblocked, from a point just above the DEM in the square up to where it leaves the
prism.

Tuning
------
``margin_m`` (default 1 mm): ten times the float32 rounding of the rays' and vertices' site-frame coordinates
(≈ 1e-4 m at the EV5 body's 300 m); a cell whose static geometry comes closer than this to the DEM is blocked.

Use
---
``square = clear_square(heights, triangles_uvz)`` with the static scene's triangles in the DEM's grid units →
:class:`ClearSquare` (``r = 0``: nothing to skip). ``tests/test_dem_clearance.py`` checks it against a brute-force
oracle and the renderer against the untiled full site.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np


@dataclass(frozen=True)
class ClearSquare:
    """The clear square (module docstring) in the DEM's grid units: centre (``u_c``, ``v_c``), half-size ``r``, and
    the cells found blocked (for the record)."""

    u_c: float
    v_c: float
    r: float
    blocked_cells: int

    def contains(self, u, v, eps: float = 1e-3):
        """Whether grid points (u, v) lie inside the square shrunk by ``eps`` cells (numpy)."""
        r = self.r - eps
        return (np.abs(np.asarray(u) - self.u_c) < r) & (np.abs(np.asarray(v) - self.v_c) < r)


@numba.njit(cache=True)
def _mark_blocked(h, tri, margin, blocked):  # pragma: no cover - numba
    """Set ``blocked[j, i]`` for every cell (i, j) that a triangle of ``tri`` (T, 3, 3: u, v, z) meets with its height
    bound not ``margin`` under the cell's lowest corner (module docstring)."""
    ny, nx = h.shape
    for k in range(tri.shape[0]):
        u0, v0, z0 = tri[k, 0, 0], tri[k, 0, 1], tri[k, 0, 2]
        u1, v1, z1 = tri[k, 1, 0], tri[k, 1, 1], tri[k, 1, 2]
        u2, v2, z2 = tri[k, 2, 0], tri[k, 2, 1], tri[k, 2, 2]
        i_lo = max(int(np.floor(min(u0, u1, u2))), 0)
        i_hi = min(int(np.floor(max(u0, u1, u2))), nx - 2)
        j_lo = max(int(np.floor(min(v0, v1, v2))), 0)
        j_hi = min(int(np.floor(max(v0, v1, v2))), ny - 2)
        if i_lo > i_hi or j_lo > j_hi:
            continue
        zmax = max(z0, z1, z2)
        det = (u1 - u0) * (v2 - v0) - (u2 - u0) * (v1 - v0)  # twice the projected area (signed)
        flat = abs(det) > 1e-12
        if flat:
            gu = ((z1 - z0) * (v2 - v0) - (z2 - z0) * (v1 - v0)) / det  # the plane z = z0 + gu·(u−u0) + gv·(v−v0)
            gv = ((u1 - u0) * (z2 - z0) - (u2 - u0) * (z1 - z0)) / det
        else:
            gu = gv = 0.0
        for j in range(j_lo, j_hi + 1):
            for i in range(i_lo, i_hi + 1):
                if flat and _separated(u0, v0, u1, v1, u2, v2, float(i), float(j)):
                    continue
                bound = zmax
                if flat:
                    pmax = z0 + gu * (i - u0) + gv * (j - v0) + max(gu, 0.0) + max(gv, 0.0)
                    bound = min(bound, pmax)
                lo = min(min(h[j, i], h[j, i + 1]), min(h[j + 1, i], h[j + 1, i + 1]))
                if bound >= lo - margin:
                    blocked[j, i] = True


@numba.njit(cache=True, inline="always")
def _separated(u0, v0, u1, v1, u2, v2, i, j):  # pragma: no cover - numba
    """Whether one of the triangle's edge lines separates it from the cell square [i, i+1] × [j, j+1] (the square's
    axes were handled by the bounding-box loop)."""
    us = (u0, u1, u2)
    vs = (v0, v1, v2)
    orient = (u1 - u0) * (v2 - v0) - (u2 - u0) * (v1 - v0)
    for e in range(3):
        ax, ay = us[e], vs[e]
        bx, by = us[(e + 1) % 3], vs[(e + 1) % 3]
        nx_, ny_ = by - ay, ax - bx  # a normal of the edge; the triangle lies on the side of sign(orient)·(−n)
        if orient > 0:
            nx_, ny_ = -nx_, -ny_
        # the triangle is on the side n·(p − a) ≥ 0; separated if every corner of the square is on the other side
        s = -1e300
        for cu in (i, i + 1.0):
            for cv in (j, j + 1.0):
                s = max(s, nx_ * (cu - ax) + ny_ * (cv - ay))
        if s < 0.0:
            return True
    return False


def clear_square(heights, triangles_uvz, margin_m: float = 1e-3) -> ClearSquare:
    """The clear square of a DEM beside static triangles (module docstring).

    Parameters
    ----------
    heights : array (ny, nx)
        The DEM's vertex heights (as the march traces them: float32 values).
    triangles_uvz : array (T, 3, 3)
        The static scene's triangles, vertices as (u, v, z) in the DEM's grid units (float64 of the values the
        renderer traces).
    margin_m : float
        See Tuning.
    """
    h = np.ascontiguousarray(heights, dtype=np.float64)
    ny, nx = h.shape
    tri = np.ascontiguousarray(np.asarray(triangles_uvz, np.float64).reshape(-1, 3, 3))
    blocked = np.zeros((ny - 1, nx - 1), bool)
    if len(tri):
        _mark_blocked(h, tri, float(margin_m), blocked)
    u_c, v_c = (nx - 1) / 2.0, (ny - 1) / 2.0
    r = min(u_c, v_c)
    jb, ib = np.nonzero(blocked)
    if len(ib):  # Chebyshev distance from the centre to each blocked cell's nearest point
        du = np.maximum(np.maximum(ib - u_c, u_c - (ib + 1.0)), 0.0)
        dv = np.maximum(np.maximum(jb - v_c, v_c - (jb + 1.0)), 0.0)
        r = min(r, float(np.maximum(du, dv).min()))
    return ClearSquare(u_c, v_c, r, int(len(ib)))
