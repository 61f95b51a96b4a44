"""The descent EKF: position/velocity in the asteroid-fixed frame, landmark pixels, a per-landmark χ² gate.

Propagation (eqs. D1–D5 of :mod:`.dynamics`): x⁻ = RK4 of D1 with the held input u, P⁻ = Φ P Φᵀ + Q_q + Q_u.
Update (eqs. M1–M5 of :mod:`.measurements`): innovation ν = z − h(x⁻), S = H P⁻ Hᵀ + R (U1). Gate (U2): landmark i
(its rows g_i) is rejected when d_i = ν_gᵀ S_gg⁻¹ ν_g > χ²_{|g|}(p_gate) — the marginal test of each landmark on its
own block of S — and, with ``reject_flagged``, when the method flagged it an outlier (Retina's final output phase,
``context["flagged"]``); with ``joint_gate``, the kept landmarks must also pass together (U2b:
ν_Kᵀ S_KK⁻¹ ν_K ≤ χ²_|K|(p_gate), the worst one dropped until they do). The kept rows update jointly: K = P⁻Hᵀ S⁻¹, x⁺ = x⁻ + Kν, Joseph form
P⁺ = (I − KH) P⁻ (I − KH)ᵀ + K R Kᵀ (U3); NIS = νᵀ S⁻¹ ν over the kept rows, dof = their number (U4).
With map states (:mod:`.map_states`) the same equations run on the augmented state: new landmarks augmented before
the gate (their prior enters S), H of eq. L1, the considered states' gain rows zero in ``"consider"`` mode; landmarks
augmented now but not kept are dropped again (nothing learnt), those absent for ``map_keep_updates`` updates
marginalised (L3). With ``iterations`` > 1 the update is the iterated EKF (U5; Bar-Shalom, Li & Kirubarajan 2001,
§10.5.2): x_{i+1} = x⁻ + K_i (z − h(x_i) − H_i (x⁻ − x_i)), H_i and K_i at x_i, P⁺ by U3 with the last K_i, H_i.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from estimators.descent_nav import dynamics
from estimators.descent_nav.map_states import MODES, MapStates, landmark_context, map_jacobian
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
    map_states : str
        Landmark map-error states (:mod:`.map_states`): ``"off"`` (none: the map is exact), ``"estimate"``
        (augmented-state EKF, eqs. L1–L4) or ``"consider"`` (Schmidt–Kalman: carried, never updated). On, a
        ``"pixel"`` measurement needs ``context["landmark_ids"]`` and ``context["landmark_cov_m2"]``.
    map_keep_updates : int
        A landmark's map states are marginalised after this many consecutive updates without it (eq. L3).
    joint_gate : bool
        After the per-landmark gate, test the kept landmarks *jointly* (eq. U2b): while their NIS exceeds
        χ²_dof(p_gate), drop the landmark whose removal lowers it most. Catches false matches that each fit the
        prior's wide marginal S but not each other (several wrong locks after a large initial error).
    iterations : int
        Gauss–Newton iterations of the update (eq. U5, the iterated EKF); 1 = the EKF. The gate and NIS use the
        prior's linearisation.
    """

    gm_m3_s2: float = 0.0
    omega_rad_s: tuple = (0.0, 0.0, 0.0)
    q_acc_m2_s3: float = 0.0
    sigma_input_mps2: float = 0.0
    gate_probability: float = 1.0 - 1e-6
    reject_flagged: bool = True
    max_step_s: float = 10.0
    map_states: str = "off"
    map_keep_updates: int = 3
    joint_gate: bool = False
    iterations: int = 1

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
        if self.map_states not in MODES:
            raise UserError(f"{NAME}: map_states must be one of {', '.join(MODES)}, got {self.map_states!r}")
        if not (isinstance(self.iterations, int) and 1 <= self.iterations <= 50):
            raise UserError(f"{NAME}: iterations must be an integer in [1, 50], got {self.iterations!r}")
        if not (isinstance(self.map_keep_updates, int) and self.map_keep_updates >= 1):
            raise UserError(f"{NAME}: map_keep_updates must be an integer >= 1, got {self.map_keep_updates!r}")


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
    m/s²) until the next call; call it once per accelerometer sample, then ``propagate`` to that sample's end.
    ``x``, ``P``: the navigation state [r, v] and its covariance; with map states, ``xa``, ``Pa`` are the whole
    augmented state and ``map_ids`` the landmarks whose map errors it holds (in that order)."""

    def __init__(self, options: DescentNavOptions | None = None):
        self.options = options or DescentNavOptions()
        self._omega = np.asarray(self.options.omega_rad_s, float)
        self._gate, self._q = {}, {}
        self.t = self._x = self._P = None
        self.u = np.zeros(3)
        self._maps = MapStates(self.options.map_keep_updates)

    @property
    def x(self):
        return None if self._x is None else self._x[:6]

    @property
    def P(self):
        return None if self._P is None else self._P[:6, :6]

    @property
    def xa(self):
        return self._x

    @property
    def Pa(self):
        return self._P

    @property
    def map_ids(self) -> list[int]:
        return list(self._maps.ids)

    @property
    def map_reaugmented(self) -> int:
        """Landmarks augmented again after their states were marginalised (:mod:`.map_states`)."""
        return self._maps.reaugmented

    def initialize(self, t0_s: float, x0, P0) -> None:
        self.t = float(_finite(t0_s, (), "t0_s"))
        x = _finite(x0, (6,), "x0")
        P = _finite(P0, (6, 6), "P0")
        if not np.allclose(P, P.T) or np.linalg.eigvalsh(0.5 * (P + P.T))[0] <= 0:
            raise UserError(f"{NAME}: P0 must be symmetric positive definite")
        self._x, self._P = x, 0.5 * (P + P.T)
        self._maps.reset()

    def _check(self):
        if self._x is None:
            raise UserError(f"{NAME}: initialize the filter before propagating or updating it")

    def set_input(self, u_mps2) -> None:
        self.u = _finite(u_mps2, (3,), "the input acceleration")

    def propagate(self, t_s: float) -> None:
        """Eqs. D1–D5; map states constant (eq. L4: Φ_a = blkdiag(Φ, I))."""
        self._check()
        dt = float(t_s) - self.t
        if dt == 0.0:
            return
        o = self.options
        x, phi = dynamics.propagate(self._x[:6], dt, o.gm_m3_s2, self._omega, self.u, o.max_step_s)
        if dt not in self._q:
            self._q[dt] = dynamics.white_acceleration_q(dt, o.q_acc_m2_s3) + dynamics.held_input_q(dt,
                                                                                                o.sigma_input_mps2)
        P = self._P.copy()
        P[:6, :6] = phi @ self._P[:6, :6] @ phi.T + self._q[dt]
        P[:6, 6:] = phi @ self._P[:6, 6:]
        P[6:, :6] = P[:6, 6:].T
        self._x = np.concatenate([x, self._x[6:]])
        self._P = 0.5 * (P + P.T)
        self.t = float(t_s)

    def _threshold(self, dof: int) -> float:
        if dof not in self._gate:
            from scipy.stats import chi2

            p = self.options.gate_probability
            self._gate[dof] = math.inf if p >= 1.0 else float(chi2.ppf(p, dof))
        return self._gate[dof]

    def _with_maps(self, kind: str, context: dict):
        """Slot of each landmark in the state, or None without map states; augments new landmarks (eq. L2)."""
        if self.options.map_states == "off" or kind != "pixel" or "points_body_m" not in context:
            return None
        pts = np.asarray(context["points_body_m"], float)
        if pts.ndim != 2 or pts.shape[1] != 3:
            return None                              # the measurement model gives the one-line error
        ids, covs = landmark_context(context, len(pts), NAME)
        self._x, self._P = self._maps.augment(self._x, self._P, ids, covs)
        return self._maps.slots(ids)

    def _linearise(self, kind: str, xa: np.ndarray, z: np.ndarray, R, context: dict, slots):
        """(ν, H, R, groups) at the whole state ``xa``: the landmarks at their map-corrected points (eq. L1)."""
        ctx = context
        if slots is not None:
            ctx = {**context, "points_body_m": np.asarray(context["points_body_m"], float)
                   + xa[6:].reshape(-1, 3)[slots]}
        nu, H6, Rm, groups = model(kind, xa[:6], z, R, ctx, NAME)
        n = len(xa)
        H = map_jacobian(H6, slots, n) if slots is not None else np.hstack([H6, np.zeros((len(nu), n - 6))])
        return nu, H, Rm, groups

    def _close_maps(self, context: dict, slots, kept: np.ndarray) -> None:
        """Drop the landmarks augmented now but not kept (nothing learnt: exact), then the stale ones (eq. L3)."""
        if slots is None:
            if self.options.map_states != "off":
                self._x, self._P = self._maps.remove(self._x, self._P, self._maps.end_update([]))
            return
        ids = np.asarray(context["landmark_ids"]).reshape(-1)
        fresh = [int(j) for j, k in zip(slots, kept) if not k and self._maps.seen[j] == self._maps.count]
        self._x, self._P = self._maps.remove(self._x, self._P, fresh, forget=True)
        used = ids[kept]
        self._x, self._P = self._maps.remove(self._x, self._P, self._maps.end_update(used))

    def _joint_gate(self, nu: np.ndarray, S: np.ndarray, groups: list, kept: np.ndarray) -> np.ndarray:
        """Landmarks to drop so that the kept ones pass jointly (eq. U2b: ν_Kᵀ S_KK⁻¹ ν_K ≤ χ²_|K|(p_gate)),
        greedily, the one whose removal lowers the joint NIS most first; (k,) bool."""
        keep = list(np.flatnonzero(kept))
        drop = np.zeros(len(groups), bool)

        def nis(idx):
            rows = np.concatenate([groups[i] for i in idx])
            return float(nu[rows] @ np.linalg.solve(S[np.ix_(rows, rows)], nu[rows])), len(rows)

        while len(keep) > 1:
            d, dof = nis(keep)
            if d <= self._threshold(dof):
                break
            worst = min(keep, key=lambda i: nis([j for j in keep if j != i])[0])
            keep.remove(worst)
            drop[worst] = True
        return drop

    def _gain(self, S: np.ndarray, H: np.ndarray) -> np.ndarray:
        K = np.linalg.solve(S, H @ self._P).T
        if self.options.map_states == "consider":
            K[6:] = 0.0                              # Schmidt–Kalman: the map states are considered, not estimated
        return K

    def update(self, t_s: float, kind: str, z, R, context: dict) -> DescentUpdate:
        """Propagate to ``t_s`` and update with one measurement of ``kind`` (eqs. U1–U4; map states L1–L3)."""
        self.propagate(t_s)
        z = np.array(z, dtype=float).reshape(-1)
        if not np.all(np.isfinite(z)):
            raise UserError(f"{NAME}: measurement z has non-finite values")
        context = context or {}
        slots = self._with_maps(kind, context)
        R = np.array(R, dtype=float) if R is not None else None
        nu, H, Rm, groups = self._linearise(kind, self._x, z, R, context, slots)
        if Rm is None or Rm.shape != (len(nu), len(nu)) or not np.all(np.isfinite(Rm)):
            raise UserError(f"{NAME}: R must be a finite ({len(nu)}, {len(nu)}) covariance for this {kind!r} "
                            f"measurement")
        n = len(self._x)
        k = len(groups)
        flagged = np.zeros(k, bool)
        if self.options.reject_flagged and "flagged" in context:
            flagged = np.asarray(context["flagged"], bool).reshape(-1)
            if flagged.shape != (k,):
                raise UserError(f"{NAME}: context 'flagged' must have one entry per landmark ({k})")
        S = H @ self._P @ H.T + Rm
        d2 = _gate_statistics(nu, S, groups)
        gated = ~flagged & (d2 > np.array([self._threshold(len(g)) for g in groups]))
        kept = ~flagged & ~gated
        if self.options.joint_gate and kept.sum() > 1:
            gated |= self._joint_gate(nu, S, groups, kept)
            kept = ~flagged & ~gated
        if not kept.any():
            self._close_maps(context, slots, kept)
            return DescentUpdate(math.nan, 0, kept, flagged, gated, d2)
        rows = np.concatenate([g for g, keep in zip(groups, kept) if keep])
        nu, H, Rk, S = nu[rows], H[rows], Rm[np.ix_(rows, rows)], S[np.ix_(rows, rows)]
        K = self._gain(S, H)
        dx = K @ nu
        for _ in range(self.options.iterations - 1):    # iterated EKF (U5): relinearise at x⁻ + δx
            nu_i, H_i, _, _ = self._linearise(kind, self._x + dx, z, R, context, slots)
            H = H_i[rows]
            K = self._gain(H @ self._P @ H.T + Rk, H)
            dx = K @ (nu_i[rows] + H @ dx)
        IKH = np.eye(n) - K @ H
        self._x = self._x + dx
        P = IKH @ self._P @ IKH.T + K @ Rk @ K.T
        self._P = 0.5 * (P + P.T)
        self._close_maps(context, slots, kept)
        return DescentUpdate(float(nu @ np.linalg.solve(S, nu)), len(rows), kept, flagged, gated, d2)
