r"""Gauge-free stage-1 quantities and their Cramér–Rao σ (Ivanov et al. 2018, eqs. 5-7).

The body frame of θ (eq. 5) is the principal-axes frame, and which axis is called 1, 2, 3 — and how well
its orientation is fixed — is only as good as the inertia ratios (weak on short arcs). Quantities that do
not depend on that frame are what the images fix directly:

* the reference points in LVLH at the epoch, ``q_j = r0 + R0 p_j`` (R0 = R_lvlh_from_body at the epoch);
* the angular velocity in LVLH at the epoch, ``R0 ω0``, and its magnitude ``‖ω0‖``;
* the trace-normalised inertia tensor in LVLH, ``R0 diag(I) R0ᵀ / tr I`` (6 upper-triangle elements).

Their covariance is the CRLB of θ, ``(JᵀJ)⁻¹`` of the whitened residuals (the inverse of the Fisher
information of eq. 7), propagated through the Jacobian G = ∂g/∂θ (central differences; g needs no
propagation of eq. 2, so this is cheap): ``C_g = G (JᵀJ)⁺ Gᵀ``. The pseudo-inverse drops null directions
of F (in the ratio parametrisation there are none; see :mod:`.observability`). Body-frame σ's, by
contrast, combine per-axis terms that are strongly correlated with the weak attitude direction and can be
orders of magnitude larger than those of the same quantities in LVLH.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .onboard_model import exp_so3
from .stage1 import Stage1Problem


@dataclass
class GaugeFree:
    """Gauge-free quantities at the epoch and their 1σ (CRLB)."""

    points_lvlh: np.ndarray        # (M, 3) r0 + R0 p_j, m
    points_sigma: np.ndarray       # (M, 3) 1σ per LVLH axis, m
    omega_lvlh: np.ndarray         # (3,) R0 ω0, rad/s
    omega_sigma: np.ndarray        # (3,)
    omega_norm: float              # ‖ω0‖, rad/s
    omega_norm_sigma: float
    inertia_lvlh: np.ndarray       # (6,) upper triangle of R0 diag(I) R0ᵀ / tr I
    inertia_sigma: np.ndarray      # (6,)
    cov: np.ndarray                # full covariance of g = [points (3M), ω (3), ‖ω‖, inertia (6)]


def gauge_free_vector(problem: Stage1Problem, theta: np.ndarray) -> np.ndarray:
    """g(θ) = [r0 + R0 p_j (3M), R0 ω0 (3), ‖ω0‖, trace-normalised LVLH inertia tensor (6)]."""
    r0, _, dphi, w0, inertia, pts = problem.unpack(theta)
    R0 = problem.R_ref @ exp_so3(dphi)
    T = R0 @ np.diag(inertia) @ R0.T
    T = T / np.trace(T)
    return np.r_[(r0 + pts @ R0.T).ravel(), R0 @ w0, np.linalg.norm(w0), T[np.triu_indices(3)]]


def gauge_free(problem: Stage1Problem, theta: np.ndarray, step: float = 1e-6) -> GaugeFree:
    """The gauge-free quantities at ``theta`` (ratio parametrisation) with their CRLB covariance."""
    g = gauge_free_vector(problem, theta)
    G = np.empty((len(g), len(theta)))
    for c in range(len(theta)):
        h = np.zeros(len(theta))
        h[c] = step
        G[:, c] = (gauge_free_vector(problem, theta + h) - gauge_free_vector(problem, theta - h)) / (2 * step)
    J = problem.jacobian(theta)
    cov = G @ np.linalg.pinv(J.T @ J) @ G.T
    sig = np.sqrt(np.clip(np.diag(cov), 0, None))
    m = 3 * problem.db.n_points
    return GaugeFree(g[:m].reshape(-1, 3), sig[:m].reshape(-1, 3), g[m:m + 3], sig[m:m + 3], float(g[m + 3]),
                     float(sig[m + 3]), g[m + 4:], sig[m + 4:], cov)
