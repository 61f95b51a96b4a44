"""The error budget's shadow-approximation term: configuration ``no_shadows`` (:mod:`.runner`).

What the onboard methods do with cast shadows, and why "off" switches both sides:

* **Retina** (``retina``, ``retina_refined``, ``retina_ml``) and the **NCC baseline** render their template by ray casting the
  maplet (:func:`estimators.retina.predict.render_template`) and cast a shadow ray toward the Sun from every
  hit (``TemplateOptions.shadow_rays``) — against the maplet's own relief only: a shadow cast from outside the
  maplet, or by relief the maplet smooths, is missing from the template.
* **SPC** shades its grid and marches toward the Sun in whole cells (``SpcOptions.cast_shadows``, the
  horizon march) and drops the points it predicts in shadow.

Their *shadow approximation* is the difference between these predictions and the truth's ray-traced cast
shadows. It exists only where the truth has cast shadows, so switching it **off** means: the truth rendered
without cast shadows (``render.shadows = false``: every surface facing the Sun is lit) **and** the onboard
predictions without cast shadows (Retina / NCC without shadow rays, SPC without the horizon march; attached
shadows, cos i ≤ 0, stay on both sides and are modelled exactly up to the maplet's normals). Both sides then
agree on the shadowing exactly. Switching only the truth off would leave the methods predicting shadows the
image lacks (a new error, not the absence of the approximation); switching only the methods off would
measure "no shadow model" against the approximate one.

The term is measured at the all-off point, like the peak step: ``no_shadows`` is every source off plus no
cast shadows; the shadow term is ``sign(d)·√|d|`` with d = v²(all off) − v²(no shadows) (:mod:`.report`).
It is part of the all-off residual, so it does not enter the quadrature sum (which starts from all off).
"""

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
    """The landmark-method object ``obj`` with its prediction's cast shadows switched off (module docstring).

    Known by what the object carries: Retina-family ``options.template`` (a TemplateOptions), the NCC
    baseline's ``template_options``, SPC's ``options.cast_shadows``. UserError for a method with none of them."""
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
