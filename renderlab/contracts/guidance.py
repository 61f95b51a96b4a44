"""The guidance-law contract: estimated state in, commanded acceleration out, in the asteroid-fixed frame.

A guidance plug-in is a factory ``make(options: GuidanceOptions) -> GuidanceLaw`` registered in
:data:`renderlab.plugins.guidance` (built in: ``zem_zev``). The lab calls ``command(t_s, x_est)`` once per control
period with the navigation filter's estimate and holds the returned acceleration over the period (zero-order hold);
the thrusters then add their errors. Everything is SI, in the frame the waypoints are given in (EV5: ``EV5_FIXED``,
turning at ``omega_rad_s`` with respect to inertial space).

Rules: ``command`` returns a finite (3,) array and does not modify its input; the same calls in the same order give
the same commands (a law may keep state between calls, e.g. the waypoint it flies to); a law that cannot fly the
request raises :class:`~renderlab.errors.UserError` when made.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np


@dataclass(frozen=True)
class GuidanceWaypoint:
    """A target state at a time: ``t_s`` (s), ``r_m`` (3,) m, ``v_mps`` (3,) m/s."""

    t_s: float
    r_m: tuple
    v_mps: tuple


@dataclass(frozen=True)
class GuidanceOptions:
    """What every guidance law is made with.

    Attributes
    ----------
    waypoints : tuple of GuidanceWaypoint
        In increasing time; the last is the touchdown target (surface point and touchdown velocity).
    gm_m3_s2 : float
        Onboard point-mass GM (the law's gravity model), m³/s².
    omega_rad_s : tuple of 3 float
        Spin vector of the frame with respect to inertial space, frame axes, rad/s.
    control_period_s : float
        Period each command is held for, s.
    max_accel_mps2 : float
        Thrust limit over the vehicle's mass, m/s².
    params : dict
        Law-specific knobs by name (a law ignores the ones it has no use for).
    """

    waypoints: tuple
    gm_m3_s2: float
    omega_rad_s: tuple = (0.0, 0.0, 0.0)
    control_period_s: float = 1.0
    max_accel_mps2: float = math.inf
    params: dict = field(default_factory=dict)


@runtime_checkable
class GuidanceLaw(Protocol):
    """A guidance law (module docstring)."""

    name: str

    def command(self, t_s: float, x_est: np.ndarray) -> np.ndarray: ...
