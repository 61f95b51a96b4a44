"""The descent EKF: position/velocity in the asteroid-fixed frame, landmark pixels, a per-landmark χ² gate.

Propagation (eqs. D1–D5 of :mod:`.dynamics`): x⁻ = RK4 of D1 with the held input u, P⁻ = Φ P Φᵀ + Q_q + Q_u.
Update (eqs. M1–M5 of :mod:`.measurements`): innovation ν = z − h(x⁻), S = H P⁻ Hᵀ + R (U1). Gate (U2): landmark i
(its rows g_i) is rejected when d_i = ν_gᵀ S_gg⁻¹ ν_g > χ²_{|g|}(p_gate) — the marginal test of each landmark on its
own block of S — and, with ``reject_flagged``, when the method flagged it an outlier (Retina's final output phase,
``context["flagged"]``). The kept rows update jointly: K = P⁻Hᵀ S⁻¹, x⁺ = x⁻ + Kν, Joseph form
P⁺ = (I − KH) P⁻ (I − KH)ᵀ + K R Kᵀ (U3); NIS = νᵀ S⁻¹ ν over the kept rows, dof = their number (U4).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from estimators.descent_nav import dynamics
from estimators.descent_nav.measurements import model
from renderlab.errors import UserError

NAME = "descent_ekf"


@dataclass(frozen=True)
class DescentNavOptions:
    """Filter model and tuning (SI units).

    Attributes
    ----------
    gm_m3_s2 : float
        Onboard point-mass GM μ (eq. D1), m³/s².
    omega_rad_s : tuple of 3 float
        Angular velocity of the asteroid-fixed frame w.r.t. inertial space, body axes, rad/s.
    q_acc_m2_s3 : float
        PSD of the white unmodelled acceleration per axis (eq. D4), m²/s³.
    sigma_input_mps2 : float
        1σ per axis of the accelerometer input, held over each input interval (eq. D5), m/s².
    gate_probability : float
        Per-landmark χ² gate probability (eq. U2); 1.0 switches the gate off.
    reject_flagged : bool
        Reject landmarks the method flagged as outliers (``context["flagged"]``).
    max_step_s : float
        Longest RK4 step, s.
    """

    gm_m3_s2: float = 0.0
    omega_rad_s: tuple = (0.0, 0.0, 0.0)
    q_acc_m2_s3: float = 0.0
    sigma_input_mps2: float = 0.0
    gate_probability: float = 1.0 - 1e-6
    reject_flagged: bool = True
    max_step_s: float = 10.0

    def __post_init__(self):
        w = np.asarray(self.omega_rad_s, float)
        if w.shape != (3,) or not np.all(np.isfinite(w)):
            raise UserError(f"{NAME}: omega_rad_s must be 3 finite numbers, got {self.omega_rad_s!r}")
        object.__setattr__(self, "omega_rad_s", tuple(float(v) for v in w))
        for name in ("gm_m3_s2", "q_acc_m2_s3", "sigma_input_mps2"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise UserError(f"{NAME}: {name} must be a finite number >= 0, got {v!r}")
        if not 0.0 < self.gate_probability <= 1.0:
            raise UserError(f"{NAME}: gate_probability must be in (0, 1], got {self.gate_probability!r}")
        if not (self.max_step_s > 0 and math.isfinite(self.max_step_s)):
            raise UserError(f"{NAME}: max_step_s must be positive, got {self.max_step_s!r}")


@dataclass(frozen=True)
class DescentUpdate:
    """One update: NIS and dof over the kept landmarks (eq. U4), which landmarks were kept, and why not."""

    nis: float
    dof: int
    kept: np.ndarray       # (k,) bool
    flagged: np.ndarray    # (k,) bool: rejected as the method's outlier
    gated: np.ndarray      # (k,) bool: rejected by the χ² gate
    d2: np.ndarray         # (k,) the gate statistic of each landmark


def _finite(a, shape, what: str) -> np.ndarray:
    v = np.array(a, dtype=float)
    if v.shape != shape or not np.all(np.isfinite(v)):
        raise UserError(f"{NAME}: {what} must be finite with shape {shape}, got shape {v.shape}"
                        + ("" if v.shape != shape else " with non-finite values"))
    return v


def _gate_statistics(nu: np.ndarray, S: np.ndarray, groups: list) -> np.ndarray:
    """d_i = ν_gᵀ S_gg⁻¹ ν_g per landmark (eq. U2), one batched solve."""
    idx = np.array(groups)                                   # (k, m): every group of a kind has the same size
    blocks = S[idx[:, :, None], idx[:, None, :]]              # (k, m, m)
    v = nu[idx]
    return np.einsum("ki,ki->k", v, np.linalg.solve(blocks, v[..., None])[..., 0])


class DescentEKF:
    """Onboard descent EKF (module docstring). ``set_input(u)`` holds the accelerometer's reading (body frame,
    m/s²) until the next call; call it once per accelerometer sample, then ``propagate`` to that sample's end."""

    def __init__(self, options: DescentNavOptions | None = None):
        self.options = options or DescentNavOptions()
        self._omega = np.asarray(self.options.omega_rad_s, float)
        self._gate, self._q = {}, {}
        self.t = self.x = self.P = None
        self.u = np.zeros(3)

    def initialize(self, t0_s: float, x0, P0) -> None:
        self.t = float(_finite(t0_s, (), "t0_s"))
        self.x = _finite(x0, (6,), "x0")
        P = _finite(P0, (6, 6), "P0")
        if not np.allclose(P, P.T) or np.linalg.eigvalsh(0.5 * (P + P.T))[0] <= 0:
            raise UserError(f"{NAME}: P0 must be symmetric positive definite")
        self.P = 0.5 * (P + P.T)

    def _check(self):
        if self.x is None:
            raise UserError(f"{NAME}: initialize the filter before propagating or updating it")

    def set_input(self, u_mps2) -> None:
        self.u = _finite(u_mps2, (3,), "the input acceleration")

    def propagate(self, t_s: float) -> None:
        self._check()
        dt = float(t_s) - self.t
        if dt == 0.0:
            return
        o = self.options
        self.x, phi = dynamics.propagate(self.x, dt, o.gm_m3_s2, self._omega, self.u, o.max_step_s)
        if dt not in self._q:
            self._q[dt] = dynamics.white_acceleration_q(dt, o.q_acc_m2_s3) + dynamics.held_input_q(dt,
                                                                                                o.sigma_input_mps2)
        P = phi @ self.P @ phi.T + self._q[dt]
        self.P = 0.5 * (P + P.T)
        self.t = float(t_s)

    def _threshold(self, dof: int) -> float:
        if dof not in self._gate:
            from scipy.stats import chi2

            p = self.options.gate_probability
            self._gate[dof] = math.inf if p >= 1.0 else float(chi2.ppf(p, dof))
        return self._gate[dof]

    def update(self, t_s: float, kind: str, z, R, context: dict) -> DescentUpdate:
        """Propagate to ``t_s`` and update with one measurement of ``kind`` (eqs. U1–U4)."""
        self.propagate(t_s)
        z = np.array(z, dtype=float).reshape(-1)
        if not np.all(np.isfinite(z)):
            raise UserError(f"{NAME}: measurement z has non-finite values")
        nu, H, Rm, groups = model(kind, self.x, z, np.array(R, dtype=float) if R is not None else None,
                                  context, NAME)
        if Rm is None or Rm.shape != (len(nu), len(nu)) or not np.all(np.isfinite(Rm)):
            raise UserError(f"{NAME}: R must be a finite ({len(nu)}, {len(nu)}) covariance for this {kind!r} "
                            f"measurement")
        k = len(groups)
        flagged = np.zeros(k, bool)
        if self.options.reject_flagged and "flagged" in context:
            flagged = np.asarray(context["flagged"], bool).reshape(-1)
            if flagged.shape != (k,):
                raise UserError(f"{NAME}: context 'flagged' must have one entry per landmark ({k})")
        S = H @ self.P @ H.T + Rm
        d2 = _gate_statistics(nu, S, groups)
        gated = ~flagged & (d2 > np.array([self._threshold(len(g)) for g in groups]))
        kept = ~flagged & ~gated
        if not kept.any():
            return DescentUpdate(math.nan, 0, kept, flagged, gated, d2)
        rows = np.concatenate([g for g, keep in zip(groups, kept) if keep])
        nu, H, Rk, S = nu[rows], H[rows], Rm[np.ix_(rows, rows)], S[np.ix_(rows, rows)]
        K = np.linalg.solve(S, H @ self.P).T
        IKH = np.eye(6) - K @ H
        self.x = self.x + K @ nu
        P = IKH @ self.P @ IKH.T + K @ Rk @ K.T
        self.P = 0.5 * (P + P.T)
        return DescentUpdate(float(nu @ np.linalg.solve(S, nu)), len(rows), kept, flagged, gated, d2)
