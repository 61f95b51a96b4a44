r"""Physical inertia ratios: a parametrisation in which every value satisfies the triangle inequality.

Stage 1 (Ivanov et al. 2018, eq. 5) estimates the inertia only up to scale (eq. 2 depends on ratios;
eq. 7 shows the scale unobservable), as (ln(I1/I3), ln(I2/I3)). Positivity alone is not enough: a
rigid body's principal moments are I1 = s2 + s3, I2 = s1 + s3, I3 = s1 + s2 with the principal second
moments of mass s_i = ∫ x_i² dm ≥ 0, so I_i + I_j ≥ I_k. An unconstrained solver on a short arc can
walk out of that set (I1 + I2 < I3: no body has such moments). Here the solver works instead on

    u = (ln(s1/s3), ln(s2/s3)),     s = (e^{u1}, e^{u2}, 1) up to scale,

so every u ∈ ℝ² is a physical body (strictly: s_i > 0, the flat-body boundary s3 = 0 is approached,
not reached), and :func:`log_ratios_from_u` maps it back to the log-ratios the onboard model uses,
with its 2×2 Jacobian for the chain rule.
"""

from __future__ import annotations

import numpy as np


def is_physical(inertia, tol: float = 0.0) -> bool:
    """Positive moments that satisfy I_i + I_j ≥ I_k (relative tolerance ``tol``)."""
    i = np.asarray(inertia, float)
    s = i.sum()
    return bool(np.all(i > 0) and np.all(s - 2 * i >= -tol * s))


def log_ratios_from_u(u) -> tuple[np.ndarray, np.ndarray]:
    """(ln(I1/I3), ln(I2/I3)) and its Jacobian ∂/∂u (2×2) for s = (e^{u1}, e^{u2}, 1)."""
    u1, u2 = np.asarray(u, float)
    l12 = np.logaddexp(u1, u2)                     # overflow-free: ln(e^{u1} + e^{u2})
    ln = np.array([np.logaddexp(u2, 0.0) - l12, np.logaddexp(u1, 0.0) - l12])
    a1, a2 = np.exp(u1 - l12), np.exp(u2 - l12)    # s1/(s1+s2), s2/(s1+s2)
    b1, b2 = np.exp(u1 - np.logaddexp(u1, 0.0)), np.exp(u2 - np.logaddexp(u2, 0.0))  # s_i/(s_i+s3)
    J = np.array([[-a1, b2 - a2], [b1 - a1, -a2]])
    return ln, J


def u_from_ratios(ratios, margin: float = 1e-3) -> np.ndarray:
    """Inverse map for physical ratios (I1/I3, I2/I3); an unphysical guess is first moved inside the
    feasible set (each s_i at least ``margin`` of the trace)."""
    i = np.r_[np.asarray(ratios, float), 1.0]
    if np.any(i <= 0):
        raise ValueError(f"inertia ratios must be positive, got {ratios}")
    s = np.array([i[1] + i[2] - i[0], i[0] + i[2] - i[1], i[0] + i[1] - i[2]]) / 2
    s = np.maximum(s, margin * i.sum())
    return np.log(s[:2] / s[2])
