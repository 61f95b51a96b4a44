"""ARRM descent over the landing site, in the EV5 body-fixed frame (Wright et al., §Concept of operations).

On-board navigation starts near 1 km; the spacecraft passes a 200 m waypoint, matches the spin at
50 m and descends to the surface. Altitude h(t) above the site centre o along its normal n:
smoothstep transfers 1 km → 200 m (``transfer_to_waypoint_s``) and 200 m → 50 m
(``transfer_to_spin_match_s``), zero velocity at each waypoint, then a constant-rate descent.

* Above the spin-match altitude the spacecraft is on a line fixed in inertial space (the site
  normal as it points at the spin-match time t_m), so in the body frame it turns with the sun:
  p_B(t) = Rz(ω (t_m − t)) (o + h(t) n).
* Below, it is spin-matched: p_B(t) = o + h(t) n.
* The sun is inertially fixed: s_B(t) = Rz(ω (t_m − t)) s_B(t_m), with s_B(t_m) at phase angle
  ``phase_deg`` from n toward azimuth ``sun_azimuth_deg`` (from site east toward north).
* The camera looks at o with body +z (the spin pole) toward the top of the image.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from renderlab.dynamics.camera_paths import CameraPose
from renderlab.dynamics.small_body import SpinState
from renderlab.errors import UserError
from renderlab.geometry.rotations import look_at


@dataclass(frozen=True)
class DescentState:
    """One sample of the descent: time, altitude, camera pose and sun (body frame); ``spin_matched`` None for a
    file trajectory (:mod:`.file_trajectory`)."""

    time_s: float
    altitude_m: float
    pose: CameraPose
    sun_dir_body: np.ndarray
    spin_matched: bool | None


class DescentProfile:
    """Altitude profile h(t) and its inverse (module docstring)."""

    def __init__(self, traj):
        self.traj = traj
        self.h = [traj.start_altitude_m, traj.waypoint_altitude_m, traj.spin_match_altitude_m, traj.final_altitude_m]
        d3 = (traj.spin_match_altitude_m - traj.final_altitude_m) / traj.descent_rate_mps
        self.t = np.cumsum([0.0, traj.transfer_to_waypoint_s, traj.transfer_to_spin_match_s, d3])

    @property
    def t_spin_match(self) -> float:
        return float(self.t[2])

    @property
    def duration(self) -> float:
        return float(self.t[3])

    def altitude(self, t) -> np.ndarray:
        t = np.clip(np.asarray(t, float), 0.0, self.duration)
        out = np.empty_like(t)
        for k in range(3):
            m = (t >= self.t[k]) & (t <= self.t[k + 1])
            tau = (t[m] - self.t[k]) / (self.t[k + 1] - self.t[k])
            s = tau if k == 2 else tau * tau * (3 - 2 * tau)
            out[m] = self.h[k] + (self.h[k + 1] - self.h[k]) * s
        return out

    def time_at(self, altitude) -> np.ndarray:
        """Inverse of :meth:`altitude` (monotonic), by bisection to 1e-9 s."""
        a = np.asarray(altitude, float)
        lo, hi = np.zeros_like(a), np.full_like(a, self.duration)
        for _ in range(80):
            mid = 0.5 * (lo + hi)
            above = self.altitude(mid) > a
            lo, hi = np.where(above, mid, lo), np.where(above, hi, mid)
        return 0.5 * (lo + hi)


def frame_times(traj, profile: DescentProfile) -> np.ndarray:
    """Times of the frames (``sampling``: geometric in altitude, ``altitudes_m``, or a frame rate)."""
    if traj.altitudes_m is not None:
        return profile.time_at(np.array(traj.altitudes_m, float))
    if traj.sampling == "rate":
        t = traj.start_time_s + np.arange(traj.frames) / traj.frame_rate_hz
        if t[-1] > profile.duration + 1e-9:
            raise UserError(f"trajectory: {traj.frames} frames at {traj.frame_rate_hz:g} Hz from "
                            f"{traj.start_time_s:g} s run past the end of the descent ({profile.duration:.0f} s)")
        return t
    alts = np.geomspace(traj.start_altitude_m, traj.final_altitude_m, traj.frames) if traj.frames > 1 \
        else np.array([traj.start_altitude_m])
    return profile.time_at(alts)


def sun_at_spin_match(origin_normal_east_north, traj) -> np.ndarray:
    n, e, no = origin_normal_east_north
    g, az = math.radians(traj.phase_deg), math.radians(traj.sun_azimuth_deg)
    s = math.cos(g) * n + math.sin(g) * (math.cos(az) * e + math.sin(az) * no)
    return s / np.linalg.norm(s)


def descent_states(traj, spin: SpinState, origin: np.ndarray, R_body_from_site: np.ndarray) -> list[DescentState]:
    """Camera poses and sun directions of every frame (body frame)."""
    profile = DescentProfile(traj)
    e, no, n = R_body_from_site[:, 0], R_body_from_site[:, 1], R_body_from_site[:, 2]
    s_m = sun_at_spin_match((n, e, no), traj)
    out = []
    for t in frame_times(traj, profile):
        h = float(profile.altitude(t))
        dt = profile.t_spin_match - t
        turn = spin.inertial_to_body_turn(-dt)[0]  # Rz(ω (t_m − t))
        matched = t >= profile.t_spin_match
        pos = origin + h * n
        if not matched:
            pos = turn.apply(pos)
        sun = turn.apply(s_m)
        up = np.array([0.0, 0.0, 1.0])
        if abs(np.dot(up, (origin - pos) / np.linalg.norm(origin - pos))) > 0.99:
            up = e
        pose = CameraPose(time_s=float(t), position_m=pos, rotation=look_at(pos, origin, up))
        out.append(DescentState(float(t), h, pose, sun, bool(matched)))
    return out
