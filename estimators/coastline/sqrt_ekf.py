r"""Square-root (array-form QR) version of the coastline EKF, for the numerical-conditioning check.

Same model and same measurements as :class:`.ekf.BatchCoastlineEKF` (Straub & Christian eqs. 3, 6-19), but the
filter carries a square root S of the covariance, :math:`P = SS^T`, so P can never lose symmetry or positive
definiteness, and the conditioning that matters is that of S (the square root of P's).

- Propagation (eq. 3, STM form): :math:`S^- = \Phi S` (with process noise: the triangular factor of
  :math:`[\Phi S,\ L_Q]`, by QR).
- Measurement: each LOS is expressed in a 2-D tangent basis :math:`(\mathbf a_i, \mathbf b_i) \perp
  \hat{\mathbf e}_i` of its predicted direction, :math:`z_i = [\mathbf a_i, \mathbf b_i]^T\mathbf y_i`,
  :math:`\hat z_i = 0`, :math:`H_i = [\mathbf a_i, \mathbf b_i]^T H_i^{(17)}`. The rank-2 R of eq. 18 becomes the
  full-rank :math:`\sigma_\theta^2 I_2` (plus the shared star-tracker term :math:`\sigma_{att}^2 BB^T`,
  :math:`B_i = [\mathbf a_i, \mathbf b_i]^T[\hat{\mathbf e}_i\times]`), so no pseudo-inverse (eq. 19) is needed;
  to first order this is the same update, because eq. 19's gain discards exactly the component along e.
- Update (array form): QR of the pre-array :math:`\begin{bmatrix}R^{1/2} & HS\\ 0 & S\end{bmatrix}^T` gives the
  lower-triangular post-array :math:`\begin{bmatrix}W & 0\\ \bar K & S^+\end{bmatrix}`, :math:`WW^T = HPH^T+R`,
  :math:`K = \bar K W^{-1}`, and :math:`S^+` is the updated square root (Joseph-stable by construction).
- NIS :math:`= \|W^{-1}\boldsymbol\nu\|^2` with 2m degrees of freedom; NEES :math:`= \|S^{-1}\tilde{\mathbf x}\|^2`.
"""

from __future__ import annotations

import numpy as np

from .dynamics import propagate_state_stm, white_acceleration_qd
from .ekf import EKFOptions, UpdateResult
from .los import los_jacobian_position, los_predict, skew_batch

__all__ = ["SqrtBatchCoastlineEKF", "tangent_basis"]


def tangent_basis(e: np.ndarray) -> np.ndarray:
    """Orthonormal (a, b) ⟂ e for unit vectors e (..., 3) → (..., 2, 3) (rows a, b)."""
    helper = np.where(np.abs(e[..., :1]) < 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    a = np.cross(e, helper)
    a /= np.linalg.norm(a, axis=-1, keepdims=True)
    b = np.cross(e, a)
    return np.stack([a, b], -2)


def _lower_factor(A: np.ndarray) -> np.ndarray:
    """Lower-triangular L with L Lᵀ = A Aᵀ for A (N, n, k), k ≥ n, by QR of Aᵀ."""
    r = np.linalg.qr(np.swapaxes(A, -1, -2), mode="r")
    return np.swapaxes(r, -1, -2)[..., :, : A.shape[-2]]


class SqrtBatchCoastlineEKF:
    """N square-root coastline EKFs in lock-step (same interface as :class:`.ekf.BatchCoastlineEKF`)."""

    def __init__(self, x0: np.ndarray, P0: np.ndarray, options: EKFOptions = EKFOptions()):
        self.options = options
        self.x = np.array(x0, dtype=np.float64, ndmin=2)
        N = self.x.shape[0]
        self.S = np.array(np.broadcast_to(np.linalg.cholesky(np.asarray(P0, np.float64)), (N, 6, 6)))

    @property
    def P(self) -> np.ndarray:
        return np.matmul(self.S, np.swapaxes(self.S, -1, -2))

    @property
    def n_runs(self) -> int:
        return self.x.shape[0]

    def nees(self, err: np.ndarray) -> np.ndarray:
        """‖S⁻¹ x̃‖² for errors (N, 6)."""
        w = np.linalg.solve(self.S, err[..., None])[..., 0]
        return np.einsum("ni,ni->n", w, w)

    def propagate(self, dt: float) -> np.ndarray:
        o = self.options
        self.x, phi = propagate_state_stm(self.x, dt, o.mu_m3_s2, o.max_step_s)
        S = np.matmul(phi, self.S)
        if o.q_acc_m2_s3 > 0.0:
            Lq = np.linalg.cholesky(white_acceleration_qd(dt, o.q_acc_m2_s3) + 1e-300 * np.eye(6))
            S = _lower_factor(np.concatenate([S, np.broadcast_to(Lq, S.shape)], -1))
        else:
            S = _lower_factor(S)
        self.S = S
        return phi

    def update(self, y_cam: np.ndarray, o_inertial: np.ndarray, T_cam_from_inertial: np.ndarray) -> UpdateResult:
        o = self.options
        N = self.n_runs
        y = np.asarray(y_cam, np.float64)
        m = y.shape[1]
        if m == 0:
            return UpdateResult(nis=np.zeros(N), dof=0, innovation=np.zeros((N, 0)))
        e_c, e_i, rho = los_predict(self.x[:, :3], o_inertial, T_cam_from_inertial)
        Bt = tangent_basis(e_c)                                                  # (N, m, 2, 3)
        H3 = los_jacobian_position(e_i, rho, T_cam_from_inertial)               # (N, m, 3, 3), eq. 17
        Hr = np.matmul(Bt, H3).reshape(N, 2 * m, 3)
        nu = np.einsum("nmij,nmj->nmi", Bt, y).reshape(N, 2 * m)                 # z − ẑ, ẑ = 0
        R = o.sigma_theta_rad**2 * np.broadcast_to(np.eye(2 * m), (N, 2 * m, 2 * m))
        if o.sigma_attitude_rad > 0.0:
            B = np.matmul(Bt, skew_batch(e_c)).reshape(N, 2 * m, 3)
            R = R + o.sigma_attitude_rad**2 * np.matmul(B, np.swapaxes(B, -1, -2))
        Rs = np.linalg.cholesky(R)
        HS = np.matmul(Hr, self.S[:, :3, :])                                      # (N, 2m, 6)
        nz = 2 * m
        pre = np.zeros((N, nz + 6, nz + 6))
        pre[:, :nz, :nz] = Rs
        pre[:, :nz, nz:] = HS
        pre[:, nz:, nz:] = self.S
        L = _lower_factor(pre)
        W, Kb, S_new = L[:, :nz, :nz], L[:, nz:, :nz], L[:, nz:, nz:]
        w = np.linalg.solve(W, nu[..., None])[..., 0]                             # W⁻¹ ν
        self.x = self.x + np.einsum("nij,nj->ni", Kb, w)                          # K ν = K̄ W⁻¹ ν
        self.S = S_new
        return UpdateResult(nis=np.einsum("ni,ni->n", w, w), dof=nz, innovation=nu)
