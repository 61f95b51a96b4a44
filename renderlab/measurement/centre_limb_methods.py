"""The lab's centre/limb methods (``estimators.centre_limb``) as methods of the centre/limb contract
(:mod:`renderlab.contracts.centre_limb`): each takes a :class:`~renderlab.contracts.centre_limb.CentreLimbFrame` and
returns a checked :class:`~renderlab.contracts.centre_limb.CentreLimbResult`; an exception inside the estimator becomes
``method_error`` with its message in ``diagnostics``.

=================  =========================================================================================
name               method
=================  =========================================================================================
``centroid_raw``   centre of brightness, no correction (the baseline)
``centroid_phase`` centre of brightness with the Lambert phase correction and the perspective shift (eqs. 8–12)
``limb_ellipse``   limb scan + direct least-squares ellipse fit → body position (eqs. 13–14, 19–20)
``horizon_opnav``  limb scan + Christian–Robinson non-iterative horizon OpNav (eqs. 13–18)
=================  =========================================================================================

A factory takes an optional options object of the estimator (``CentroidOptions``, ``EllipseOptions``,
``HorizonOptions``); None gives the defaults. They are registered for the ``centre_limb`` kind
(:func:`renderlab.plugins.method_registry`), beside Basilisk's modules (:mod:`renderlab.basilisk.opnav_methods`).
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from estimators.centre_limb import (
    CentroidOptions,
    EllipseOptions,
    HorizonOpNav,
    HorizonOptions,
    IntensityCentroid,
    LimbEllipse,
)
from renderlab.contracts.centre_limb import CentreLimbFrame, CentreLimbReason, CentreLimbResult


def result_from_estimate(est) -> CentreLimbResult:
    """An ``estimators.centre_limb.Estimate`` → a checked :class:`CentreLimbResult` (same fields)."""
    res = CentreLimbResult(**{f.name: getattr(est, f.name) for f in dataclasses.fields(CentreLimbResult)})
    res.cov_centre_px2 = np.asarray(res.cov_centre_px2, float)
    res.r_cam_m = np.asarray(res.r_cam_m, float)
    res.cov_r_cam_m2 = np.asarray(res.cov_r_cam_m2, float)
    res.limb_points = np.asarray(res.limb_points, float).reshape(-1, 2)
    res.check()
    return res


class _Adapter:
    """Wrap an estimator object (``measure(frame) -> Estimate``) as a centre/limb method."""

    name = ""

    def __init__(self, estimator):
        self.estimator = estimator

    def measure(self, frame: CentreLimbFrame) -> CentreLimbResult:
        t0 = time.perf_counter()
        try:
            est = self.estimator.measure(frame)
        except Exception as exc:  # noqa: BLE001 - any estimator failure is a reported no-result
            return CentreLimbResult(reason=CentreLimbReason.METHOD_ERROR.value,
                                    diagnostics=f"{type(exc).__name__}: {exc}", t_ms=(time.perf_counter() - t0) * 1e3)
        return result_from_estimate(est)


class RawCentroidMethod(_Adapter):
    """``centroid_raw``: the centre of brightness, uncorrected."""

    name = "centroid_raw"

    def __init__(self, options=None):
        opts = options or CentroidOptions(phase_correction="none", perspective=False)
        super().__init__(IntensityCentroid(opts))


class PhaseCentroidMethod(_Adapter):
    """``centroid_phase``: the centre of brightness with the phase and perspective corrections."""

    name = "centroid_phase"

    def __init__(self, options=None):
        super().__init__(IntensityCentroid(options or CentroidOptions()))


class LimbEllipseMethod(_Adapter):
    """``limb_ellipse``: limb scan + ellipse fit."""

    name = "limb_ellipse"

    def __init__(self, options=None):
        super().__init__(LimbEllipse(options or EllipseOptions()))


class HorizonOpNavMethod(_Adapter):
    """``horizon_opnav``: Christian–Robinson horizon-based OpNav."""

    name = "horizon_opnav"

    def __init__(self, options=None):
        super().__init__(HorizonOpNav(options or HorizonOptions()))


#: name → factory of the lab's centre/limb methods (registered as ``renderlab.plugins.method_registry("centre_limb")``)
BUILTIN = {m.name: m for m in (RawCentroidMethod, PhaseCentroidMethod, LimbEllipseMethod, HorizonOpNavMethod)}
