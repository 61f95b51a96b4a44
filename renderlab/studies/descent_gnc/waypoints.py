"""The ARRM descent as guidance waypoints in the asteroid-fixed frame, and the state the closed loop starts from:
the 200 m waypoint at rest in inertial space (W1), the spin-matched 50 m waypoint (W2), the end of the
constant-rate descent (W3) and touchdown on the site DEM under the target (W4); derivation in ``docs/descent_gnc.md``.
"""

from __future__ import annotations

import math

import numpy as np

from renderlab.contracts.guidance import GuidanceWaypoint
from renderlab.errors import UserError


def _rz(theta: float) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def arrm_waypoints(profile, omega_rad_s: float, site, *, target_xy=(0.0, 0.0), touchdown_speed_mps: float = 0.05,
                   via_final_altitude: bool = True) -> tuple[float, np.ndarray, tuple]:
    """(t_start, x_start (6,), waypoints) from the 200 m waypoint to touchdown (W1–W4, module docstring): ``profile``
    the ARRM :class:`~renderlab.worlds.ev5.descent.DescentProfile`, ``omega_rad_s`` the spin about body +z, ``site``
    with ``origin_m``, ``R_body_from_site`` (east, north, up) and ``height_at(x, y)``, the touchdown point
    ``target_xy`` (site east, north, m) reached at ``touchdown_speed_mps`` (> 0) along −n."""
    if not touchdown_speed_mps > 0:
        raise UserError(f"touchdown speed must be positive, got {touchdown_speed_mps}")
    o, R = np.asarray(site.origin_m, float), np.asarray(site.R_body_from_site, float)
    n = R[:, 2]
    w = np.array([0.0, 0.0, float(omega_rad_s)])
    h_w, h_m, h_f = profile.h[1], profile.h[2], profile.h[3]
    t_w, t_m, t_f = float(profile.t[1]), float(profile.t[2]), float(profile.t[3])
    rate = float(profile.traj.descent_rate_mps)
    r0 = _rz(omega_rad_s * (t_m - t_w)) @ (o + h_w * n)                                   # W1
    x0 = np.r_[r0, -np.cross(w, r0)]
    wps = [GuidanceWaypoint(t_m, tuple(o + h_m * n), (0.0, 0.0, 0.0))]                 # W2
    h_t = float(site.height_at(float(target_xy[0]), float(target_xy[1])))
    p_t = o + R @ np.array([float(target_xy[0]), float(target_xy[1]), h_t])
    if via_final_altitude:
        wps.append(GuidanceWaypoint(t_f, tuple(o + h_f * n), tuple(-rate * n)))          # W3
        t_t = t_f + 2.0 * (h_f - h_t) / (rate + touchdown_speed_mps)
    else:
        t_t = t_m + 2.0 * (h_m - h_t) / touchdown_speed_mps
    if not t_t > wps[-1].t_s:
        raise UserError(f"the touchdown target is {h_t:.2f} m above the site centre, above the last waypoint")
    wps.append(GuidanceWaypoint(float(t_t), tuple(p_t), tuple(-touchdown_speed_mps * n)))  # W4
    return t_w, x0, tuple(wps)
