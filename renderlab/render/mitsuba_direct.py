"""``rl_direct_sun``: a Mitsuba 3 integrator for direct sunlight (one delta sun), two rays per sample.

Description
-----------
The radiance of a surface point lit by a directional sun of irradiance E (a delta emitter) and seen
along ``-ray.d`` is, with the lab's BSDF convention (:mod:`renderlab.render.mitsuba_bsdf`: ``eval`` returns
the radiance factor r = f·cos θ_sun)::

    L = E · r(μ0, μ, g) · V            (V = 1 when the sun is visible from the point, else 0)

which is the single-bounce term of the rendering equation (J. T. Kajiya, "The rendering equation", SIGGRAPH '86,
Computer Graphics 20(4), 1986, eq. 1, with one delta light source). Per sample the integrator traces the primary
ray, samples the sun (``Scene.sample_emitter_direction``: for a directional emitter the direction is exact, the
weight is E, the 2-D sample is unused), evaluates the BSDF once, and traces one shadow ray (the emitter
sampler's own test, ``spawn_ray_to``) when ``shadows`` is true (V = 1 without it) and the BSDF's value is not
zero there (a surface turned from the sun stays dark whatever the visibility: no ray). Mitsuba's ``path``
integrator with ``max_depth = 2`` computes the same L but also draws a BSDF sample and traces a third,
continuation ray that can never hit a delta emitter (zero contribution), and evaluates the BSDF twice
(``eval_pdf_sample``). Given the same primary ray both give the same value (no random number enters L for a
delta sun): ``tests/test_shadows_switch.py`` checks the images agree to float32 rounding.

Tuning
------
``shadows`` (bool, default true): false turns the shadow ray off (V = 1: every surface facing the sun is
lit; ``render.shadows``). ``hide_emitters`` is accepted for compatibility and has no effect (a
directional sun is never hit by a ray).

Use
---
:func:`register_direct_sun` once per Mitsuba variant (after
:func:`renderlab.render.variant.init_mitsuba`), then ``{"type": "rl_direct_sun", "shadows": False}`` in a
scene dict, or ``mi.load_dict`` it and pass it to ``mi.render(scene, integrator=...)``. The lab's
:class:`renderlab.render.mitsuba_backend.MitsubaBackend` uses it whenever ``max_depth = 2``
(:func:`integrator_dict`; ``MitsubaBackend.integrator = "path"`` selects Mitsuba's ``path`` for comparisons). It supports
one directional emitter (the lab's sun); with several emitters Mitsuba's emitter sampling picks one per
sample and the estimate stays unbiased.
"""

from __future__ import annotations

from renderlab.errors import UserError

NAME = "rl_direct_sun"
_registered: set[str] = set()


def _build_class(mi, dr):
    """The integrator class for the active variant (it must subclass that variant's SamplingIntegrator)."""

    scalar = not dr.is_jit_v(mi.Float)

    class DirectSun(mi.SamplingIntegrator):
        def __init__(self, props):
            mi.SamplingIntegrator.__init__(self, props)
            self.shadows = bool(props.get("shadows", True))
            props.get("hide_emitters", True)  # accepted (and marked as queried): the sun is never hit

        def sample(self, scene, sampler, ray, medium=None, active=True):
            si = scene.ray_intersect(ray, ray_flags=mi.RayFlags.All, coherent=True, active=active)
            valid = si.is_valid() & active
            if scalar and not valid:  # scalar variants: no BSDF (null pointer) without a hit
                return mi.Spectrum(0.0), False, []
            bsdf = si.bsdf(ray)
            ds, em_weight = scene.sample_emitter_direction(si, sampler.next_2d(valid), False, valid)
            lit = valid & (ds.pdf != 0.0)
            value = bsdf.eval(mi.BSDFContext(), si, si.to_local(ds.d), lit)
            if self.shadows:  # the emitter's own visibility test, only where the BSDF sends sunlight
                lit = lit & dr.any(value != 0.0)
                lit = dr.select(scene.ray_test(si.spawn_ray_to(ds.p), lit), False, lit)  # (scalar: Python bools)
            return dr.select(lit, em_weight * value, 0.0), valid, []

        def aov_names(self):
            return []

        def to_string(self):
            return f"DirectSun[shadows={self.shadows}]"

    return DirectSun


def register_direct_sun(mi) -> None:
    """Register ``rl_direct_sun`` for the active Mitsuba variant (idempotent)."""
    import drjit as dr

    variant = mi.variant()
    if variant in _registered:
        return
    cls = _build_class(mi, dr)
    mi.register_integrator(NAME, lambda props: cls(props))
    _registered.add(variant)


KINDS = ("auto", "path", "direct")


def integrator_dict(max_depth: int, shadows: bool, kind: str = "auto") -> dict:
    """The scene's integrator for ``kind``: ``"direct"``, ``rl_direct_sun`` (direct sunlight, ``max_depth = 2``);
    ``"path"``, Mitsuba's ``path`` (the lab's integrator before ``rl_direct_sun``, kept for the benchmarks); ``"auto"``,
    ``rl_direct_sun`` for direct sunlight (``max_depth = 2``), ``path`` for longer light paths. Shadows can be
    switched off only with ``rl_direct_sun``."""
    if kind not in KINDS:
        raise ValueError(f"integrator kind must be one of {KINDS}, got {kind!r}")
    if max_depth == 2 and kind in ("direct", "auto"):
        return {"type": NAME, "shadows": bool(shadows)}
    if not shadows:

        raise UserError(f"render.shadows = false needs the direct-sun integrator (render.max_depth = 2), "
                        f"got max_depth {max_depth} with integrator {kind!r}")
    return {"type": "path", "max_depth": int(max_depth), "hide_emitters": True}
