"""The error budget's shadow term: configuration ``no_shadows`` is all off with no cast shadows in the truth
(``render.shadows = false``) nor in the methods' predictions (why both: ``docs/retina_vs_spc.md``)."""

from __future__ import annotations

import dataclasses
import functools

from renderlab import plugins
from renderlab.errors import UserError

CONFIG = "no_shadows"
DESCRIPTION = ("every source off and no cast shadows: truth rendered with render.shadows = false, onboard "
               "predictions without cast shadows (Retina/NCC without shadow rays, SPC without the horizon march)")
OVERRIDES = {"render.shadows": False}


def without_cast_shadows(obj):
    """``obj`` (a landmark method) with its prediction's cast shadows off, known by what it carries: Retina-family
    ``options.template``, the NCC baseline's ``template_options``, SPC's ``options.cast_shadows``; else UserError."""
    opts = getattr(obj, "options", None)
    if opts is not None and hasattr(getattr(opts, "template", None), "shadow_rays"):
        obj.options = dataclasses.replace(opts, template=dataclasses.replace(opts.template, shadow_rays=False))
    elif hasattr(getattr(obj, "template_options", None), "shadow_rays"):
        obj.template_options = dataclasses.replace(obj.template_options, shadow_rays=False)
    elif opts is not None and hasattr(opts, "cast_shadows"):
        obj.options = dataclasses.replace(opts, cast_shadows=False)
    else:
        raise UserError(f"error budget: landmark method {getattr(obj, 'name', obj)!r} has no cast-shadow switch "
                        "(template shadow_rays or cast_shadows)")
    return obj


def _make(name: str, mopts):
    return without_cast_shadows(plugins.landmark_methods.get(name, where="error budget: ")(mopts))


def factories(names) -> list:
    """Factories (:func:`renderlab.measurement.runner.make_method` accepts them) of the named registered methods
    with cast shadows off."""
    return [functools.partial(_make, n) for n in names]
