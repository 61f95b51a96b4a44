"""The closed GN&C loop: navigation → guidance → thrusters → truth dynamics, every control period until contact.

At t_k = t_0 + kΔ the navigation estimates the true state (``navigation.estimate(t_k, x_true)``; default the truth),
the guidance law commands (``guidance.command(t_k, x_est)``, :mod:`renderlab.contracts.guidance`), the thrusters
deliver (``thrusters.realise(a_cmd, Δ)``, e.g. :class:`estimators.gnc.ThrusterModel`; default the command) and the
truth (:class:`renderlab.dynamics.descent_truth.DescentTruth`) carries the state to t_{k+1} with it held, or to
contact. A navigation with ``after_step(t0, t1, a_delivered)`` is told what was applied (an accelerometer, a
filter's propagation). Used by study ``descent_gnc`` (image navigation), the guidance tests and benchmarks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from renderlab.errors import UserError


@dataclass
class Flight:
    """One flown descent: control times then the end time ``t_s`` (K + 1,), the true state there ``x_true``
    (K + 1, 6; the last at contact), the estimate each command was made from ``x_est`` (K, 6), the commanded and
    delivered accelerations ``a_cmd``, ``a_delivered`` (K, 3) m/s², and whether it ended in contact."""

    t_s: np.ndarray
    x_true: np.ndarray
    x_est: np.ndarray
    a_cmd: np.ndarray
    a_delivered: np.ndarray
    touchdown: bool

    @property
    def x_touchdown(self) -> np.ndarray:
        return self.x_true[-1]

    def trajectory_bytes(self) -> bytes:
        """The whole record as bytes (reproducibility checks)."""
        return b"".join(np.ascontiguousarray(a, np.float64).tobytes() for a in
                        (self.t_s, self.x_true, self.x_est, self.a_cmd, self.a_delivered))


class TruthPlusNoise:
    """Navigation = truth + a decaying initial error + white noise: x̂(t) = x(t) + e₀ exp(−(t − t₀)/τ) + w, w ~
    N(0, diag(σ_r² I, σ_v² I)) from the seeded ``rng`` (6 normals a call); t₀ the first call's time, τ = ``decay_s``
    (inf: the error stays), e₀ = ``initial_error`` (default 0)."""

    def __init__(self, sigma_r_m: float, sigma_v_mps: float, rng: np.random.Generator, initial_error=None,
                 decay_s: float = math.inf):
        self.sigma = np.r_[np.full(3, float(sigma_r_m)), np.full(3, float(sigma_v_mps))]
        self.rng, self.decay_s = rng, float(decay_s)
        self.e0 = np.zeros(6) if initial_error is None else np.asarray(initial_error, float).reshape(6)
        self.t0 = None

    def estimate(self, t_s: float, x_true: np.ndarray) -> np.ndarray:
        if self.t0 is None:
            self.t0 = float(t_s)
        fade = math.exp(-(float(t_s) - self.t0) / self.decay_s)
        return x_true + fade * self.e0 + self.sigma * self.rng.standard_normal(6)


class _Perfect:
    def estimate(self, t_s, x_true):
        return np.array(x_true, float)


def fly(truth, guidance, t0_s: float, x0, *, control_period_s: float, t_max_s: float, navigation=None,
        thrusters=None) -> Flight:
    """Fly the loop of the module docstring from (t0, x0) until contact or ``t_max_s``."""
    if not control_period_s > 0 or not t_max_s > t0_s:
        raise UserError("closed loop: control_period_s must be positive and t_max_s after t0_s")
    nav = navigation if navigation is not None else _Perfect()
    after = getattr(nav, "after_step", None)
    x = np.array(x0, float)
    ts, xs, xe, ac, ad = [float(t0_s)], [x.copy()], [], [], []
    t, touchdown = float(t0_s), False
    n_steps = int(math.ceil((t_max_s - t0_s) / control_period_s - 1e-9))
    for k in range(n_steps):
        t1 = min(float(t0_s) + (k + 1) * control_period_s, float(t_max_s))
        est = np.asarray(nav.estimate(t, x), float)
        a_c = np.asarray(guidance.command(t, est), float)
        a_d = thrusters.realise(a_c, t1 - t) if thrusters is not None else a_c
        st = truth.step(t, x, t1, a_d)
        if after is not None:
            after(t, st.t_s, a_d)
        xe.append(est)
        ac.append(a_c)
        ad.append(np.asarray(a_d, float))
        t, x = st.t_s, st.x
        ts.append(t)
        xs.append(x.copy())
        if st.contact:
            touchdown = True
            break
    return Flight(np.array(ts), np.array(xs), np.array(xe).reshape(-1, 6), np.array(ac).reshape(-1, 3),
                  np.array(ad).reshape(-1, 3), touchdown)
