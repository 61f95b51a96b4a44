"""The built-in guidance law ``zem_zev`` (:data:`renderlab.plugins.guidance`) behind the lab's contract
(:mod:`renderlab.contracts.guidance`), beside the built-in method and filter adapters: :class:`ZemZevLaw` makes the
onboard :class:`estimators.gnc.zem_zev.ZemZevGuidance` (eqs. G1–G5 there) from the lab's
:class:`~renderlab.contracts.guidance.GuidanceOptions`. ``options.params`` may set ``prediction_step_s`` and
``min_t_go_s``; a ``control_period_s`` of 0 selects the continuous gains (G3).
"""

from __future__ import annotations

import numpy as np

from estimators.gnc import Waypoint, ZemZevGuidance, ZemZevOptions
from renderlab.contracts.guidance import GuidanceOptions
from renderlab.errors import UserError

_PARAMS = ("prediction_step_s", "min_t_go_s")


class ZemZevLaw:
    """Registered guidance law ``zem_zev`` (module docstring)."""

    name = "zem_zev"

    def __init__(self, options: GuidanceOptions):
        unknown = sorted(set(options.params) - set(_PARAMS))
        if unknown:
            raise UserError(f"guidance 'zem_zev': unknown parameter(s) {', '.join(unknown)} (known: "
                            f"{', '.join(_PARAMS)})")
        wps = tuple(Waypoint(float(w.t_s), tuple(map(float, w.r_m)), tuple(map(float, w.v_mps)))
                    for w in options.waypoints)
        self.law = ZemZevGuidance(ZemZevOptions(
            waypoints=wps, gm_m3_s2=float(options.gm_m3_s2), omega_rad_s=tuple(map(float, options.omega_rad_s)),
            control_period_s=float(options.control_period_s), max_accel_mps2=float(options.max_accel_mps2),
            **{k: float(v) for k, v in options.params.items()}))

    @property
    def last(self):
        """The onboard law's record of its last command (waypoint, t_go, ZEM, ZEV, saturated)."""
        return self.law.last

    def command(self, t_s: float, x_est) -> np.ndarray:
        return self.law.command(float(t_s), np.array(x_est, float))
