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
        self.surfaces = []
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
            self.surfaces.append((march, mesh, M, c))

    def update(self, frame) -> None:
        """Nothing changes per frame (the DEMs are traced at full resolution)."""

    def _site_rays(self, ray, M, c):
        """``ray``'s origin and direction in a site frame: Mᵀ(o − c), Mᵀd."""
        mi = self.backend.mi
        o = [sum(float(M[k, a]) * (ray.o[k] - float(c[k])) for k in range(3)) for a in range(3)]
        d = [sum(float(M[k, a]) * ray.d[k] for k in range(3)) for a in range(3)]
        return mi.Vector3f(*o), mi.Vector3f(*d)

    def _dem_hit(self, ray, active):
        """The nearest DEM hit along ``ray`` as a ``PreliminaryIntersection3f`` on the surfaces' meshes."""
        mi, dr = self.backend.mi, self.backend.dr
        n = dr.width(ray.d)
        pi = dr.zeros(mi.PreliminaryIntersection3f, n)
        for march, mesh, M, c in self.surfaces:
            o, d = self._site_rays(ray, M, c)
            h = march.intersect(o, d, dr.minimum(ray.maxt, pi.t))
            take = h.valid & active & (h.t < pi.t)
            face = mi.UInt32(2 * (h.j * (march.nx - 1) + h.i) + h.tri)
            pi.t = dr.select(take, h.t, pi.t)
            pi.prim_index = dr.select(take, face, pi.prim_index)
            pi.prim_uv = dr.select(take, mi.Point2f(h.b1, h.b2), pi.prim_uv)
            pi.shape = dr.select(take, mi.ShapePtr(mesh), pi.shape)
            pi.valid = pi.valid | take
        return pi

    def occluded(self, ray, active=True):
        """Bool per ray: a DEM triangle lies on ``ray`` within (0, maxt]."""
        dr = self.backend.dr
        hit = dr.zeros(self.backend.mi.Bool, dr.width(ray.d))
        for march, _, M, c in self.surfaces:
            o, d = self._site_rays(ray, M, c)
            hit |= march.occluded(o, d, dr.select(active & ~hit, ray.maxt, 0.0))
        return hit

    def first_hit(self, ray, coherent: bool = True, active=True):
        """The surface interaction of the nearer of the DEM hit and the static scene's (the DEM wins exact ties)."""
        return nearer_hit(self.backend, self._dem_hit(ray, active), ray, coherent, active)

    def direct_sun(self, sampler, ray):
        """Radiance along ``ray``: E · r(μ0, μ, g) · V (:mod:`renderlab.render.mitsuba_direct`) over DEMs + static."""
        return direct_sun_over(self.backend, self, sampler, ray, self.occluded)
