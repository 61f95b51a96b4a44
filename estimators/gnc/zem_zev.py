r"""ZEM/ZEV waypoint guidance in the rotating asteroid-fixed frame, with a sampled-data (zero-order-hold) form.

Zero-effort miss and velocity (Y. Guo, M. Hawkins, B. Wie, "Applications of generalized zero-effort-miss/zero-
effort-velocity feedback guidance algorithm", J. Guidance, Control, and Dynamics 36(3), 2013,
doi:10.2514/1.58099): with the target state (r_f, v_f) at t_f and t_go = t_f − t,

.. math::

    \mathrm{ZEM} = \mathbf r_f - \hat{\mathbf r}(t_f),\qquad \mathrm{ZEV} = \mathbf v_f - \hat{\mathbf v}(t_f)
    \quad (G1)

where (r̂, v̂) is the state the vehicle would reach with no further control. Here that *predicted* motion carries
the rotating frame (the onboard model of :mod:`estimators.descent_nav.dynamics`, eq. D1 with u = 0):

.. math::

    \dot{\hat{\mathbf v}} = -\mu\hat{\mathbf r}/\hat r^3 - 2\,\boldsymbol\omega\times\hat{\mathbf v}
        - \boldsymbol\omega\times(\boldsymbol\omega\times\hat{\mathbf r})   \quad (G2)

(point-mass gravity of the onboard GM, Coriolis and centrifugal terms), integrated by RK4 over t_go. The energy-
optimal feedback for a control entering as a double integrator (B. Ebrahimi, M. Bahrami, J. Roshanian, "Optimal
sliding-mode guidance with terminal velocity constraint for fixed-interval propulsive maneuvers", Acta Astronautica
62 (2008), doi:10.1016/j.actaastro.2008.01.011; Guo et al. 2013, with their gains 6 and 2) is

.. math::

    \mathbf a = \frac{6}{t_{go}^2}\,\mathrm{ZEM} - \frac{2}{t_{go}}\,\mathrm{ZEV}   \quad (G3)

A flight computer holds each command over its control period Δ. Held that way, G3 still brings an undisturbed
double integrator onto the target, but it is not the minimum-energy sequence of holds and it cannot correct an error
that enters in the last two periods (its gains assume a command that keeps changing). The sampled-data form used by
default is the minimum-energy piecewise-constant control over the remaining intervals k = 0 … N−1 (lengths Δ_k,
midpoints m_k, d_k = t_go − m_k) that hits ZEM and ZEV exactly, of which the first interval's value is applied:

.. math::

    \mathbf u_k = \boldsymbol\lambda_r d_k + \boldsymbol\lambda_v,\quad
    \begin{bmatrix}\sum\Delta_k d_k^2 & \sum\Delta_k d_k\\ \sum\Delta_k d_k & \sum\Delta_k\end{bmatrix}
    \begin{bmatrix}\boldsymbol\lambda_r^T\\ \boldsymbol\lambda_v^T\end{bmatrix} =
    \begin{bmatrix}\mathrm{ZEM}^T\\ \mathrm{ZEV}^T\end{bmatrix},\quad \mathbf a = \mathbf u_0   \quad (G4)

(the position a constant u_k adds at t_f is u_k Δ_k d_k, the velocity u_k Δ_k). As Δ → 0 the sums become the
integrals and G4 becomes G3. On the last interval (N = 1) the matrix is singular and the two one-interval solutions
2 ZEM/Δ² and ZEV/Δ — equal when the previous command was followed — are averaged.

Waypoints: the law flies to the first waypoint later than now, then to the next (200 m → 50 m spin-matched →
surface at the target with the touchdown velocity). After the last waypoint's time it holds the touchdown velocity
until contact: :math:`\mathbf a = -\hat{\mathbf a}_{free}(\mathbf x) + (\mathbf v_f - \mathbf v)/\Delta` (G5).
Commands are clipped to ``max_accel_mps2`` in magnitude. Pure numpy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from renderlab.errors import UserError

NAME = "zem_zev"


@dataclass(frozen=True)
class Waypoint:
    """A target state at a time, asteroid-fixed frame: ``t_s`` (s), ``r_m`` (3,) m, ``v_mps`` (3,) m/s."""

    t_s: float
    r_m: tuple
    v_mps: tuple


@dataclass(frozen=True)
class ZemZevOptions:
    """Model and tuning of :class:`ZemZevGuidance` (SI units; module docstring).

    Attributes
    ----------
    waypoints : tuple of Waypoint
        In increasing time; the last is the touchdown target (surface point, touchdown velocity).
    gm_m3_s2 : float
        Onboard point-mass GM of the prediction (eq. G2).
    omega_rad_s : tuple of 3 float
        Spin vector of the asteroid-fixed frame, body axes (eq. G2).
    control_period_s : float
        Period the command is held for (sampled-data law G4); 0 uses the continuous gains of G3.
    max_accel_mps2 : float
        Largest commanded acceleration magnitude.
    prediction_step_s : float
        Longest RK4 step of the zero-effort prediction.
    min_t_go_s : float
        With the continuous law (G3), t_go is not taken below this (its gains grow without bound).
    """

    waypoints: tuple
    gm_m3_s2: float
    omega_rad_s: tuple = (0.0, 0.0, 0.0)
    control_period_s: float = 1.0
    max_accel_mps2: float = math.inf
    prediction_step_s: float = 20.0
    min_t_go_s: float = 1.0


@dataclass
class GuidanceState:
    """What the last command did: the waypoint flown to (index; −1 = touchdown hold), t_go, ZEM, ZEV."""

    waypoint: int = 0
    t_go_s: float = math.nan
    zem_m: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    zev_mps: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    saturated: bool = False


def _check(o: ZemZevOptions) -> None:
    if not o.waypoints:
        raise UserError("zem_zev guidance: give at least one waypoint")
    t = [float(w.t_s) for w in o.waypoints]
    if any(b <= a for a, b in zip(t, t[1:])):
        raise UserError("zem_zev guidance: waypoint times must increase")
    vals = [v for w in o.waypoints for v in (*w.r_m, *w.v_mps)] + [o.gm_m3_s2, *o.omega_rad_s]
    if any(not math.isfinite(float(v)) for v in vals) or any(len(w.r_m) != 3 or len(w.v_mps) != 3
                                                             for w in o.waypoints):
        raise UserError("zem_zev guidance: waypoints, GM and spin must be finite 3-vectors / numbers")
    if o.control_period_s < 0 or not o.max_accel_mps2 > 0 or not o.prediction_step_s > 0 or not o.min_t_go_s > 0:
        raise UserError("zem_zev guidance: control_period_s >= 0, max_accel_mps2, prediction_step_s and min_t_go_s "
                        "> 0")


class ZemZevGuidance:
    """ZEM/ZEV waypoint guidance (module docstring, eqs. G1–G5)."""

    name = NAME

    def __init__(self, options: ZemZevOptions):
        _check(options)
        self.options = options
        self.wp_t = np.array([float(w.t_s) for w in options.waypoints])
        self.wp_r = np.array([np.asarray(w.r_m, float) for w in options.waypoints])
        self.wp_v = np.array([np.asarray(w.v_mps, float) for w in options.waypoints])
        self.w = np.asarray(options.omega_rad_s, float)
        self._wf = tuple(float(c) for c in self.w)
        self.last = GuidanceState()

    # ------------------------------------------------------------------ the onboard model (eq. G2)
    def free_acceleration(self, r, v) -> np.ndarray:
        """Acceleration with no control: onboard gravity, Coriolis and centrifugal terms (eq. G2)."""
        return np.array(self._free(*(float(c) for c in r), *(float(c) for c in v)))

    def _free(self, x, y, z, vx, vy, vz):
        """Eq. G2 on plain floats (the prediction's inner loop)."""
        wx, wy, wz = self._wf
        mu = self.options.gm_m3_s2
        k = -mu / (x * x + y * y + z * z) ** 1.5 if mu else 0.0
        cx, cy, cz = wy * z - wz * y, wz * x - wx * z, wx * y - wy * x                   # ω × r
        return (k * x - 2.0 * (wy * vz - wz * vy) - (wy * cz - wz * cy),
                k * y - 2.0 * (wz * vx - wx * vz) - (wz * cx - wx * cz),
                k * z - 2.0 * (wx * vy - wy * vx) - (wx * cy - wy * cx))

    def predict(self, r, v, t_go: float) -> tuple[np.ndarray, np.ndarray]:
        """(r̂, v̂) after ``t_go`` s of zero-effort motion (eq. G2, classical RK4)."""
        n = max(1, int(math.ceil(t_go / self.options.prediction_step_s - 1e-12)))
        h = t_go / n
        f = self._free
        x, y, z = (float(c) for c in r)
        u, w, q = (float(c) for c in v)
        for _ in range(n):
            a1 = f(x, y, z, u, w, q)
            a2 = f(x + 0.5 * h * u, y + 0.5 * h * w, z + 0.5 * h * q,
                   u + 0.5 * h * a1[0], w + 0.5 * h * a1[1], q + 0.5 * h * a1[2])
            a3 = f(x + 0.5 * h * (u + 0.5 * h * a1[0]), y + 0.5 * h * (w + 0.5 * h * a1[1]),
                   z + 0.5 * h * (q + 0.5 * h * a1[2]),
                   u + 0.5 * h * a2[0], w + 0.5 * h * a2[1], q + 0.5 * h * a2[2])
            a4 = f(x + h * (u + 0.5 * h * a2[0]), y + h * (w + 0.5 * h * a2[1]), z + h * (q + 0.5 * h * a2[2]),
                   u + h * a3[0], w + h * a3[1], q + h * a3[2])
            # position: h (v + h/6 (a1 + a2 + a3)) — RK4 of ṙ = v with the velocity stages above
            x, y, z = (x + h * (u + h / 6.0 * (a1[0] + a2[0] + a3[0])), y + h * (w + h / 6.0 * (a1[1] + a2[1] + a3[1])),
                       z + h * (q + h / 6.0 * (a1[2] + a2[2] + a3[2])))
            u, w, q = (u + h / 6.0 * (a1[0] + 2 * a2[0] + 2 * a3[0] + a4[0]),
                       w + h / 6.0 * (a1[1] + 2 * a2[1] + 2 * a3[1] + a4[1]),
                       q + h / 6.0 * (a1[2] + 2 * a2[2] + 2 * a3[2] + a4[2]))
        return np.array([x, y, z]), np.array([u, w, q])

    # ------------------------------------------------------------------ the law
    def _sampled(self, zem: np.ndarray, zev: np.ndarray, t_go: float) -> np.ndarray:
        """First interval's control of eq. G4."""
        dt = self.options.control_period_s
        n = max(1, int(math.ceil(t_go / dt - 1e-9)))
        if n == 1:
            return 0.5 * (2.0 * zem / t_go**2 + zev / t_go)
        s = np.minimum(np.arange(n + 1) * dt, t_go)
        lengths, d = np.diff(s), t_go - 0.5 * (s[1:] + s[:-1])
        a11, a12, a22 = float(np.sum(lengths * d * d)), float(np.sum(lengths * d)), float(np.sum(lengths))
        det = a11 * a22 - a12 * a12
        lam_r, lam_v = (a22 * zem - a12 * zev) / det, (a11 * zev - a12 * zem) / det
        return lam_r * d[0] + lam_v

    def command(self, t_s: float, x_est) -> np.ndarray:
        """Commanded acceleration (3,) m/s², asteroid-fixed frame, from the estimated state ``x_est`` = [r, v]."""
        x = np.asarray(x_est, float)
        if x.shape != (6,) or not np.all(np.isfinite(x)):
            raise UserError("zem_zev guidance: the state estimate must be 6 finite numbers [r, v]")
        r, v = x[:3], x[3:]
        o = self.options
        k = int(np.searchsorted(self.wp_t, float(t_s) + 1e-9, side="left"))
        if k >= len(self.wp_t):     # past the last waypoint: hold the touchdown velocity (eq. G5)
            hold = max(o.control_period_s, o.min_t_go_s)
            a = -self.free_acceleration(r, v) + (self.wp_v[-1] - v) / hold
            self.last = GuidanceState(-1)
        else:
            t_go = float(self.wp_t[k] - t_s)
            rf, vf = self.predict(r, v, t_go)
            zem, zev = self.wp_r[k] - rf, self.wp_v[k] - vf                      # eq. G1
            if o.control_period_s > 0:
                a = self._sampled(zem, zev, t_go)                              # eq. G4
            else:
                tg = max(t_go, o.min_t_go_s)
                a = 6.0 * zem / tg**2 - 2.0 * zev / tg                         # eq. G3
            self.last = GuidanceState(k, t_go, zem, zev)
        norm = float(np.linalg.norm(a))
        if norm > o.max_accel_mps2:
            a = a * (o.max_accel_mps2 / norm)
            self.last.saturated = True
        return a
