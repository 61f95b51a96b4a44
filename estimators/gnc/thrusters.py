r"""Thruster model: the acceleration a commanded acceleration really produces over one control period.

Three opposed thruster pairs along the axes of a thruster frame T (``R_frame_from_thrusters``: the commanded
frame ← T). A command :math:`\mathbf a_c` held for Δ becomes, in order:

1. per axis i of T, the commanded impulse :math:`I_i = m\,a_{c,i}\,\Delta` clipped to the thrust limit
   (:math:`|I_i| \le m\,a_{max}\Delta`);
2. the minimum impulse bit b (the shortest pulse a valve delivers): :math:`|I_i| < b/2 \to 0`,
   :math:`b/2 \le |I_i| < b \to \mathrm{sign}(I_i)\,b`, otherwise :math:`I_i` (pulse-width modulation above it) — T1;
3. a magnitude error: the impulse vector scaled by :math:`1 + s_0 + s_k` (T2), :math:`s_0 \sim N(0, \sigma_{s0}^2)`
   drawn once (a thrust calibration bias), :math:`s_k \sim N(0, \sigma_{s}^2)` drawn per command;
4. a pointing error: rotated by :math:`\exp([\boldsymbol\theta_0 + \boldsymbol\theta_k]_\times)` (T3),
   :math:`\boldsymbol\theta_0 \sim N(0, \sigma_{m}^2 I_3)` the fixed misalignment, :math:`\boldsymbol\theta_k
   \sim N(0, \sigma_{p}^2 I_3)` per command.

The delivered acceleration (commanded frame) is the impulse over mΔ. Draws: the constructor draws 1 + 3 normals
(s_0, θ_0), every command 1 + 3 more (s_k, θ_k), whatever the σ (zero σ keeps the stream's positions), so a seed
reproduces a run. Propellant: each pair's impulse counts (:math:`\sum_i |I_i|`, L1 over the axes of T), divided by
I_sp g_0 when ``isp_s`` is given. Pure numpy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from renderlab.errors import UserError

G0 = 9.80665


@dataclass(frozen=True)
class ThrusterOptions:
    """Thruster set (module docstring). ``mass_kg`` is the vehicle's mass (constant over the descent)."""

    mass_kg: float = 1000.0
    max_accel_mps2: float = math.inf
    min_impulse_bit_ns: float = 0.0
    scale_bias_sigma: float = 0.0
    scale_sigma: float = 0.0
    misalignment_sigma_rad: float = 0.0
    pointing_sigma_rad: float = 0.0
    isp_s: float = math.nan
    R_frame_from_thrusters: tuple = field(default=((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)))


def _rotation(theta: np.ndarray) -> np.ndarray:
    """exp([θ×]) by Rodrigues' formula."""
    a = float(np.linalg.norm(theta))
    if a < 1e-300:
        return np.eye(3)
    k = theta / a
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(a) * K + (1.0 - math.cos(a)) * (K @ K)


class ThrusterModel:
    """Commanded → delivered acceleration (module docstring, T1–T3); ``rng`` a seeded numpy Generator."""

    def __init__(self, options: ThrusterOptions, rng: np.random.Generator):
        o = options
        if not o.mass_kg > 0 or o.min_impulse_bit_ns < 0 or not o.max_accel_mps2 > 0 or min(
                o.scale_bias_sigma, o.scale_sigma, o.misalignment_sigma_rad, o.pointing_sigma_rad) < 0:
            raise UserError("thrusters: mass and thrust limit must be positive, impulse bit and sigmas non-negative")
        R = np.asarray(o.R_frame_from_thrusters, float)
        if R.shape != (3, 3) or not np.allclose(R.T @ R, np.eye(3), atol=1e-9):
            raise UserError("thrusters: R_frame_from_thrusters must be a 3x3 rotation matrix")
        self.options, self.R, self.rng = o, R, rng
        self.scale0 = o.scale_bias_sigma * float(rng.standard_normal())
        self.theta0 = o.misalignment_sigma_rad * rng.standard_normal(3)
        self.impulse_ns = 0.0

    def realise(self, a_cmd, dt_s: float) -> np.ndarray:
        """The acceleration (3,) m/s² delivered over ``dt_s`` for the command ``a_cmd`` (commanded frame)."""
        o = self.options
        a = np.asarray(a_cmd, float)
        if a.shape != (3,) or not np.all(np.isfinite(a)) or not dt_s > 0:
            raise UserError("thrusters: the command must be 3 finite numbers and the period positive")
        m = o.mass_kg
        imp = np.clip(m * (self.R.T @ a) * dt_s, -m * o.max_accel_mps2 * dt_s, m * o.max_accel_mps2 * dt_s)
        b = o.min_impulse_bit_ns
        if b > 0:                                                                      # T1
            mag = np.abs(imp)
            imp = np.where(mag < 0.5 * b, 0.0, np.where(mag < b, np.sign(imp) * b, imp))
        s_k = o.scale_sigma * float(self.rng.standard_normal())
        theta_k = o.pointing_sigma_rad * self.rng.standard_normal(3)
        self.impulse_ns += float(np.abs(imp).sum())
        delivered = (1.0 + self.scale0 + s_k) * (_rotation(self.theta0 + theta_k) @ (self.R @ imp))   # T2, T3
        return delivered / (m * dt_s)

    @property
    def delta_v_mps(self) -> float:
        """Σ|I_i| / m so far (L1 over the thruster axes), m/s."""
        return self.impulse_ns / self.options.mass_kg

    @property
    def propellant_kg(self) -> float:
        """Σ|I_i| / (I_sp g0) so far (NaN without ``isp_s``)."""
        return self.impulse_ns / (self.options.isp_s * G0)
