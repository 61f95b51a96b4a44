"""Tiled surfaces in a second Mitsuba scene: the static bodies' acceleration structure is built once.

Description
-----------
Mitsuba 3 rebuilds the acceleration structure of the *whole* scene whenever any of its meshes changes: on the
full EV5 world, writing a frame's 34 k site facets into a scene that also holds the 1.3 M-facet asteroid costs
0.3–2.5 s per frame, almost all of it Embree rebuilding the static body (``benchmarks/bench_mitsuba_tile_update.py``).
This module keeps the static bodies (and the sun) in one ``mi.Scene``, built once, and the frame's tiles in a
second, small ``mi.Scene`` whose structure alone is rebuilt when the tile set changes (milliseconds). Each ray is
intersected with both:

* **nearest hit**: the tile scene is intersected first, then the static scene with the ray cut at the tile hit
  (``maxt``; Embree prunes everything beyond it), and the nearer hit is kept; the tile scene wins an exact tie (a tile is the finer model of the same surface). The surface
  interaction is computed once, for the kept hit (``PreliminaryIntersection3f.compute_surface_interaction``), as
  ``Scene.ray_intersect`` does for one scene;
* **shadow rays**: the sun is sampled in the static scene (``Scene.sample_emitter_direction`` without its
  visibility test) and the shadow ray ``si.spawn_ray_to(ds.p)`` — the ray Mitsuba's own test traces — is
  tested against both scenes (occluded if either blocks it);
* **radiance**: the direct-sun estimator of :mod:`renderlab.render.mitsuba_direct` (L = E · r · V, one BSDF
  evaluation), with the same sampler draws, so a frame equals the one-scene render of the same geometry except
  where two surfaces are hit at exactly the same distance, or where the directional sun's bounding sphere (the
  static scene's here, the merged scene's there) moves the end point of a shadow ray by float32 rounding
  (``tests/test_mitsuba_two_scene.py`` measures both renders side by side: identical on the tiny test world; on the
  reduced EV5 of ``results/error_budget`` 0, 1 and 3 of 65 536 pixels differ in its three frames, by at most
  0.013 W m⁻² sr⁻¹, and no truth AOV but one range pixel).

Tuning
------
None. :class:`renderlab.render.mitsuba_backend.MitsubaBackend` uses this design where ``tile_design = "two"``
(``$RENDERLAB_MITSUBA_TILE_DESIGN``; :func:`site_design`). The default for tiled scenes on LLVM variants with the
direct-sun integrator is the DEM march (:mod:`renderlab.render.mitsuba_dem`), which builds nothing per frame and
traces the site at full resolution; this design stays for CUDA variants (once checked on a GPU) and for the
side-by-side tests and benchmarks.

Use
---
``TileScene(backend, tiled)``; per frame ``update(frame)``; ``first_hit(ray)`` for the truth AOVs and
``direct_sun(sampler, ray)`` for the radiance.
"""

from __future__ import annotations

import numpy as np

from renderlab.errors import UserError
from renderlab.render.mitsuba_direct import integrator_dict
from renderlab.render.mitsuba_tiles import TileArrays


class TileScene:
    """The frame's tiles as a second ``mi.Scene`` beside the backend's static scene.

    Parameters
    ----------
    backend : MitsubaBackend
        Its ``scene`` holds the static bodies and the sun; its ``_register_shapes`` numbers the tile meshes.
    tiled : list of TiledSurface
    shadows : bool
        Trace shadow rays (``render.shadows``).
    """

    def __init__(self, backend, tiled: list, shadows: bool = True):
        self.backend, self.shadows = backend, bool(shadows)
        self.tiles = TileArrays(backend.origin, tiled)
        self.scene = None
        self.params = None
        self.current: tuple | None = None
        self.updates = 0  # frames that changed the tile set

    def update(self, frame) -> None:
        """Make the tile scene hold the frame's tiles (rebuilds the tile scene's structure only)."""
        want = self.tiles.wanted(frame)
        if want == self.current:
            return
        b = self.backend
        if self.scene is None:
            desc, keys = {"type": "scene"}, {}
            self.tiles.add_meshes(b, want, desc, keys)
            self.scene = b.mi.load_dict(desc, optimize=False)
            self.params = b.mi.traverse(self.scene)
            b._register_shapes(self.scene, keys)
        else:
            self.tiles.write(self.params, want, self.current)
        self.current = want
        self.updates += 1

    def first_hit(self, ray, coherent: bool = True, active=True):
        """The surface interaction of the nearer of the two scenes' hits along ``ray`` (tiles win exact ties)."""
        near = self.scene.ray_intersect_preliminary(ray, coherent=coherent, active=active)
        return nearer_hit(self.backend, near, ray, coherent, active)

    def direct_sun(self, sampler, ray):
        """Radiance along ``ray``: E · r(μ0, μ, g) · V (:mod:`renderlab.render.mitsuba_direct`) over both scenes."""
        # the tile scene's shadow test first: near the site most shadows are cast by its own relief
        return direct_sun_over(self.backend, self, sampler, ray, self.scene.ray_test)


def nearer_hit(backend, near, ray, coherent, active, static_active=None):
    """The surface interaction of the nearer of ``near`` (a preliminary intersection with the site: tiles or DEM) and
    the static scene's hit; the static scene is searched only up to ``near`` (Embree prunes the rest), only where
    ``static_active`` (default ``active``), and the site wins exact ties."""
    mi, dr = backend.mi, backend.dr
    short = type(ray)(ray)
    short.maxt = dr.minimum(ray.maxt, near.t)
    static_active = active if static_active is None else static_active
    ps = backend.scene.ray_intersect_preliminary(short, coherent=coherent, active=static_active)
    pi = dr.select(static_active & (ps.t < near.t), ps, near)
    return pi.compute_surface_interaction(ray, mi.RayFlags.All, pi.is_valid())


def direct_sun_over(backend, site, sampler, ray, site_occludes, static_occludes=None):
    """Radiance along ``ray``: E · r(μ0, μ, g) · V (:mod:`renderlab.render.mitsuba_direct`) over the site
    (``site.first_hit``; ``site_occludes(shadow_ray, active)``, tested first) and the static scene
    (``static_occludes(si, shadow_ray, active)``, default its ``ray_test``)."""
    mi, dr = backend.mi, backend.dr
    static = backend.scene
    si = site.first_hit(ray)
    valid = si.is_valid()
    bsdf = si.bsdf(ray)
    ds, em_weight = static.sample_emitter_direction(si, sampler.next_2d(valid), False, valid)
    lit = valid & (ds.pdf != 0.0)
    value = bsdf.eval(mi.BSDFContext(), si, si.to_local(ds.d), lit)
    if site.shadows:
        lit &= dr.any(value != 0.0)  # no shadow ray where the BSDF sends no sunlight: zero whatever the visibility
        shadow = si.spawn_ray_to(ds.p)
        lit &= ~site_occludes(shadow, lit)
        lit &= ~(static.ray_test(shadow, lit) if static_occludes is None else static_occludes(si, shadow, lit))
    return dr.select(lit, em_weight * value, 0.0)


def site_design(backend) -> str:
    """How ``backend`` traces tiled surfaces: ``"dem"`` (the full-resolution DEM marched beside the static scene,
    :mod:`renderlab.render.mitsuba_dem`: the default where it applies), ``"two"`` (the frame's tiles in a second
    scene, this module) or ``"merged"`` (the tiles in the one scene, :mod:`renderlab.render.mitsuba_tiles`).

    The two designs beside the static scene need the direct-sun integrator on a JIT variant; on a CUDA variant they
    are taken only when asked for (``tile_design = "dem"`` or ``"two"``: whether OptiX traces two scenes in one
    kernel is not yet checked on a device, ``benchmarks/gpu_check.sh``); scalar variants and Mitsuba's ``path``
    integrator merge."""
    design = getattr(backend, "tile_design", "auto")
    if design not in ("auto", "two", "merged", "dem"):
        raise UserError(f"Mitsuba tile design ($RENDERLAB_MITSUBA_TILE_DESIGN) must be auto, dem, two or merged, "
                        f"got {str(design)[:40]!r}")
    if design == "merged" or backend.scalar:
        return "merged"
    if backend.variant.startswith("cuda") and design == "auto":
        return "merged"
    if integrator_dict(backend.settings.max_depth, backend.settings.shadows, backend.integrator)["type"] == "path":
        return "merged"
    return "dem" if design == "auto" else design


def register_ids(id_lut: np.ndarray, reg: np.ndarray, body_ids: list[int]) -> np.ndarray:
    """``id_lut`` grown to hold registry ids ``reg`` mapped to ``body_ids`` (a new array when it must grow)."""
    need = int(reg.max()) + 2 if len(reg) else 0
    if need > len(id_lut):
        grown = np.full(need, -1, dtype=np.int32)
        grown[:len(id_lut)] = id_lut
        id_lut = grown
    for rid, bid in zip(reg, body_ids):
        id_lut[rid] = bid
    return id_lut
