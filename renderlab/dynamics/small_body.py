"""Spin state of a small body in principal-axis rotation about a fixed pole.

The body-fixed frame B has +z along the spin pole (the angular-momentum direction, so the body
turns counter-clockwise about +z) and its prime meridian (+x) at rotation angle W(t) = W0 + ω t
from the node of the equator on the ecliptic, ω = 2π / P. The pole is given in ecliptic
coordinates (λ, β); β < 0 (pole in the southern ecliptic hemisphere) is a retrograde rotator.
2008 EV5 (Busch et al. 2011, Icarus 212, 649): P = 3.725 h, retrograde, pole near (180°, −84°).

    T_eclip_from_body(t) = T_eclip_from_equator(λ, β) · Rz(W(t))

so a direction fixed in inertial space (the sun, a hovering spacecraft's line of sight) turns by
−ω t about +z as seen in the body frame. Pure numpy/scipy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from renderlab.geometry.rotations import quat_xyzw


@dataclass(frozen=True)
class SpinState:
    """Uniform rotation about a fixed pole.

    Attributes
    ----------
    pole_lambda_deg, pole_beta_deg : float
        Ecliptic longitude and latitude of the spin pole (+z of the body frame), degrees.
    period_s : float
        Sidereal rotation period, s (> 0).
    w0_rad : float
        Rotation angle of the prime meridian at t = 0, rad.
    """

    pole_lambda_deg: float = 180.0
    pole_beta_deg: float = -84.0
    period_s: float = 3.725 * 3600.0
    w0_rad: float = 0.0

    @property
    def omega_rad_s(self) -> float:
        """Spin rate ω = 2π / P about body +z, rad/s."""
        return 2.0 * math.pi / self.period_s

    @property
    def retrograde(self) -> bool:
        """True when the pole points into the southern ecliptic hemisphere."""
        return self.pole_beta_deg < 0.0

    def rotation_angle(self, t_s) -> np.ndarray:
        """W(t) = W0 + ω t, rad."""
        return self.w0_rad + self.omega_rad_s * np.asarray(t_s, float)

    def T_eclip_from_equator(self) -> Rotation:
        """Ecliptic ← body equatorial frame (z = pole, x = ascending node of the equator)."""
        lam, beta = math.radians(self.pole_lambda_deg), math.radians(self.pole_beta_deg)
        z = np.array([math.cos(beta) * math.cos(lam), math.cos(beta) * math.sin(lam), math.sin(beta)])
        x = np.cross([0.0, 0.0, 1.0], z)
        x = x / np.linalg.norm(x) if np.linalg.norm(x) > 1e-12 else np.array([1.0, 0.0, 0.0])
        return Rotation.from_matrix(np.column_stack([x, np.cross(z, x), z]))

    def T_eclip_from_body(self, t_s: float) -> Rotation:
        """Ecliptic ← body-fixed rotation at time ``t_s``."""
        return self.T_eclip_from_equator() * Rotation.from_rotvec([0.0, 0.0, float(self.rotation_angle(t_s))])

    def inertial_to_body_turn(self, dt_s) -> Rotation:
        """Rotation that carries a body-frame vector of an inertially fixed direction at time t to
        its body-frame value at t + dt: Rz(−ω dt)."""
        return Rotation.from_rotvec(np.outer(np.atleast_1d(-self.omega_rad_s * np.asarray(dt_s, float)), [0, 0, 1.0]))

    def to_dict(self, t_s: float) -> dict:
        """JSON-able spin state at ``t_s`` (for the truth-set manifest)."""
        return {"pole_lambda_deg": self.pole_lambda_deg, "pole_beta_deg": self.pole_beta_deg,
                "period_s": self.period_s, "rotation_angle_rad": float(self.rotation_angle(t_s)),
                "quat_eclip_from_body_xyzw": [float(v) for v in quat_xyzw(self.T_eclip_from_body(t_s))]}
