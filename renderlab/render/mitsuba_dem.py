"""Tiled surfaces traced by the DEM march beside the static scene: no acceleration structure built per frame.

Description
-----------
The two-scene design (:mod:`renderlab.render.mitsuba_two_scene`) still has Embree build the structure of each
frame's tiles: 10.2 s of the 171 m EV5 frame's 9.6 M level-0 facets (``benchmarks/README.md``). This design
replaces the tile scene by the exact ray march of :mod:`renderlab.render.dem_march` over each tiled surface's
full-resolution DEM (level 0 everywhere: no levels of detail, no skirts), whose max-height pyramid is built once
per site. Per ray:

* **nearest hit**: the march (site frame: p_s = Mᵀ(p − c), M = R_render_from_body · R_body_from_site) gives t,
  the face (2·(j·(n−1) + i) + triangle, the order of ``terrain.grid_faces``) and its barycentrics; they fill a
  ``PreliminaryIntersection3f`` whose shape is the site's full mesh — a ``mi.Mesh`` built once and put in no
  scene, so Embree never builds a structure for it — and the static scene is searched up to that t (the DEM wins
  exact ties, as the tiles do). The surface interaction (position, normals, the ``vertex_albedo`` attribute, the
  BSDF) is computed once for the kept hit by Mitsuba itself (``compute_surface_interaction``), as for any mesh;
* **shadow rays**: ``si.spawn_ray_to(ds.p)`` tested by the march (any hit) and by the static scene;
* **where the DEM hides the static scene** (its clear square, :mod:`renderlab.render.dem_clearance`, found once per
  site from the static triangles as Embree traces them: everything static there lies ≥ 1 mm under the DEM), the
  static scene is not searched by a camera ray from above the DEM to a DEM hit in the square, and a shadow ray from a
  DEM point in the square is tested against it only from where it leaves the square's prism. The same bytes either
  way (``tests/test_mitsuba_dem.py``); the EV5 5 m frame renders in 0.93 instead of 0.97 s (a one-off probe);
* **radiance**: the direct-sun estimator of :mod:`renderlab.render.mitsuba_direct`, as the two-scene design.

Tuning
------
None. The default for tiled surfaces on LLVM variants with the direct-sun integrator
(:func:`renderlab.render.mitsuba_two_scene.site_design`; ``$RENDERLAB_MITSUBA_TILE_DESIGN=two`` or ``merged``
choose the LOD tiles instead). The backend marks each surface ``traced_whole``, so the frame's manifest records the
full DEM (``ev5.lod``: ``tracer = "dem_march"``, no tiles, no height error). Against the LOD tiles it also traces
what they miss: relief outside the frustum casting shadows into it, and rays that slip through Embree's float32
shared tile edges onto the body underneath (``benchmarks/bench_dem_march.py`` counts them).

Use
---
``DemScene(backend, tiled)``; ``update(frame)`` (nothing per frame); ``first_hit(ray)`` for the truth AOVs and
``direct_sun(sampler, ray)`` for the radiance, as :class:`~renderlab.render.mitsuba_two_scene.TileScene`.
"""

from __future__ import annotations

import numpy as np

from renderlab.render.dem_clearance import clear_square
from renderlab.render.dem_march import DemMarch, build_pyramid, jit_module
from renderlab.render.mitsuba_two_scene import direct_sun_over, nearer_hit, register_ids


class DemScene:
    """The tiled surfaces as marched DEMs beside the backend's static scene (module docstring).

    Parameters
    ----------
    backend : MitsubaBackend
        Its ``scene`` holds the static bodies and the sun.
    tiled : list of TiledSite
        Surfaces with a ``site`` (heights, x0, cell, frame) and a ``full_body()``.
    shadows : bool
        Trace shadow rays (``render.shadows``).
    """

    def __init__(self, backend, tiled: list, shadows: bool = True):
        self.backend, self.shadows = backend, bool(shadows)
        mi, dr = backend.mi, backend.dr
        self.surfaces, self.squares = [], []
        self.updates = 0
        for k, surf in enumerate(tiled):
            site, body = surf.site, surf.full_body()
            march = DemMarch(build_pyramid(site.heights_m, site.x0_m, site.cell_m), jit=jit_module(backend.variant))
            mesh = backend._trimesh(body, f"dem{k}")  # in no scene: no acceleration structure
            R_rb = np.asarray(body.R_render_from_body, float)
            M = R_rb @ site.R_body_from_site
            c = R_rb @ site.origin_m + np.asarray(body.center_m, float) - backend.origin
            reg = np.array(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(mesh)), dtype=np.int64)
            backend._id_lut = register_ids(backend._id_lut, reg, [surf.body_id])
            square = clear_square(march.pyr.heights, self._static_uvz(march.pyr, M, c))
            self.surfaces.append((march, mesh, M, c))
            self.squares.append(square)
        self.camera_clear = [False] * len(self.surfaces)

    def _static_uvz(self, pyr, M, c) -> np.ndarray:
        """The static scene's triangles as Embree traces them (float32 render-frame vertices; a non-mesh shape as
        the 12 triangles of its bounding box) in a DEM's grid units (u, v, z), those over its footprint only."""
        mi = self.backend.mi
        tris = []
        for shape in self.backend.scene.shapes():
            if shape.is_mesh():
                params = mi.traverse(shape)
                V = np.array(params["vertex_positions"], np.float64).reshape(-1, 3)
                F = np.array(params["faces"], np.int64).reshape(-1, 3)
            else:
                b = shape.bbox()
                lo, hi = np.array(b.min, np.float64), np.array(b.max, np.float64)
                V = np.array([[(lo, hi)[(k >> a) & 1][a] for a in range(3)] for k in range(8)])
                F = np.array([[0, 1, 3], [0, 3, 2], [4, 5, 7], [4, 7, 6], [0, 1, 5], [0, 5, 4],
                              [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 3, 7], [1, 7, 5]])
            P = (V - c) @ M  # site frame: Mᵀ(p − c), row-wise
            uvz = np.column_stack([(P[:, 0] - pyr.x0_m) / pyr.cell_m, (P[:, 1] - pyr.y0_m) / pyr.cell_m, P[:, 2]])
            T = uvz[F]
            ny, nx = pyr.heights.shape
            over = ((T[:, :, 0].max(1) >= 0) & (T[:, :, 0].min(1) <= nx - 1)
                    & (T[:, :, 1].max(1) >= 0) & (T[:, :, 1].min(1) <= ny - 1))
            tris.append(T[over])
        return np.concatenate(tris) if tris else np.zeros((0, 3, 3))

    def update(self, frame) -> None:
        """Per surface, whether the camera may skip the static scene (the DEMs are traced at full resolution: nothing
        else changes): its position lies in the clear square, above the DEM (:mod:`renderlab.render.dem_clearance`)."""
        cam = np.asarray(frame.pose.position_m, float) - self.backend.origin
        for k, ((march, _, M, c), sq) in enumerate(zip(self.surfaces, self.squares)):
            pyr = march.pyr
            x, y, z = (cam - c) @ M
            u, v = (x - pyr.x0_m) / pyr.cell_m, (y - pyr.y0_m) / pyr.cell_m
            clear = bool(sq.contains(u, v, eps=1e-2))
            if clear:
                i, j = int(np.floor(u)), int(np.floor(v))
                clear = bool(z > float(pyr.heights[j:j + 2, i:i + 2].max()) + 1e-3)
            self.camera_clear[k] = clear

    def _site_rays(self, ray, M, c):
        """``ray``'s origin and direction in a site frame: Mᵀ(o − c), Mᵀd."""
        mi = self.backend.mi
        o = [sum(float(M[k, a]) * (ray.o[k] - float(c[k])) for k in range(3)) for a in range(3)]
        d = [sum(float(M[k, a]) * ray.d[k] for k in range(3)) for a in range(3)]
        return mi.Vector3f(*o), mi.Vector3f(*d)

    def _inside(self, k: int, x, y):
        """Whether site-frame points (x, y) of surface k lie in its clear square (shrunk by 0.01 cell)."""
        dr, pyr, sq = self.backend.dr, self.surfaces[k][0].pyr, self.squares[k]
        r = sq.r - 1e-2
        return ((dr.abs((x - pyr.x0_m) / pyr.cell_m - sq.u_c) < r)
                & (dr.abs((y - pyr.y0_m) / pyr.cell_m - sq.v_c) < r))

    def _dem_hit(self, ray, active):
        """The nearest DEM hit along ``ray`` as a ``PreliminaryIntersection3f`` on the surfaces' meshes, and where the
        static scene cannot come first: the camera and the hit in the surface's clear square, the camera above the DEM
        (:mod:`renderlab.render.dem_clearance`; per frame in :meth:`update`)."""
        mi, dr = self.backend.mi, self.backend.dr
        n = dr.width(ray.d)
        pi = dr.zeros(mi.PreliminaryIntersection3f, n)
        hidden = dr.zeros(mi.Bool, n)
        for k, (march, mesh, M, c) in enumerate(self.surfaces):
            o, d = self._site_rays(ray, M, c)
            h = march.intersect(o, d, dr.minimum(ray.maxt, pi.t))
            take = h.valid & active & (h.t < pi.t)
            face = mi.UInt32(2 * (h.j * (march.nx - 1) + h.i) + h.tri)
            pi.t = dr.select(take, h.t, pi.t)
            pi.prim_index = dr.select(take, face, pi.prim_index)
            pi.prim_uv = dr.select(take, mi.Point2f(h.b1, h.b2), pi.prim_uv)
            pi.shape = dr.select(take, mi.ShapePtr(mesh), pi.shape)
            pi.valid = pi.valid | take
            # the per-frame flag as an opaque value: one kernel for frames with and without a clear camera
            clear = dr.opaque(mi.Bool, self.camera_clear[k])
            hidden = dr.select(take, clear & self._inside(k, h.p[0], h.p[1]), hidden)
        return pi, hidden

    def static_occluded(self, si, shadow, active):
        """Bool per ray: the static scene blocks ``shadow`` (spawned from ``si``; tested where ``active``). A ray from
        a DEM point in its clear square that leaves on the DEM's upper side, and that the march found unblocked, is
        tested from where it leaves the square's prism: before that it runs above the DEM, and the static scene lies
        under the DEM there (:mod:`renderlab.render.dem_clearance`)."""
        mi, dr = self.backend.mi, self.backend.dr
        t_skip = dr.zeros(mi.Float, dr.width(shadow.d))
        for k, ((march, mesh, M, c), sq) in enumerate(zip(self.surfaces, self.squares)):
            if sq.r <= 1e-2:
                continue
            pyr = march.pyr
            o, d = self._site_rays(shadow, M, c)
            up = mi.Vector3f(*(float(x) for x in M[:, 2]))  # the site's +z in the render frame
            upper = dr.dot(si.n, shadow.d) * dr.dot(si.n, up) > 0
            on = active & (si.shape == mi.ShapePtr(mesh)) & upper & self._inside(k, o[0], o[1])
            half = (sq.r - 1e-2) * pyr.cell_m
            t_exit = mi.Float(dr.inf)
            for a, centre in ((0, pyr.x0_m + sq.u_c * pyr.cell_m), (1, pyr.y0_m + sq.v_c * pyr.cell_m)):
                wall = dr.select(d[a] > 0, centre + half, centre - half)
                t_exit = dr.minimum(t_exit, dr.select(d[a] == 0, dr.inf, (wall - o[a]) / d[a]))
            t_skip = dr.select(on, t_exit, t_skip)
        rest = type(shadow)(shadow)
        rest.o = shadow.o + t_skip * shadow.d
        rest.maxt = shadow.maxt - t_skip
        return self.backend.scene.ray_test(rest, active & (rest.maxt > 0))

    def occluded(self, ray, active=True):
        """Bool per ray: a DEM triangle lies on ``ray`` within (0, maxt]."""
        dr = self.backend.dr
        hit = dr.zeros(self.backend.mi.Bool, dr.width(ray.d))
        for march, _, M, c in self.surfaces:
            o, d = self._site_rays(ray, M, c)
            hit |= march.occluded(o, d, dr.select(active & ~hit, ray.maxt, 0.0))
        return hit

    def first_hit(self, ray, coherent: bool = True, active=True):
        """The surface interaction of the nearer of the DEM hit and the static scene's (the DEM wins exact ties; the
        static scene is not searched where the DEM hides it)."""
        near, hidden = self._dem_hit(ray, active)
        return nearer_hit(self.backend, near, ray, coherent, active, static_active=active & ~hidden)

    def direct_sun(self, sampler, ray):
        """Radiance along ``ray``: E · r(μ0, μ, g) · V (:mod:`renderlab.render.mitsuba_direct`) over DEMs + static."""
        return direct_sun_over(self.backend, self, sampler, ray, self.occluded, self.static_occluded)
