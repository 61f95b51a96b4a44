r"""Line-of-sight (LOS) measurement model for matched coastline points, vectorised over runs and points.

Theory (Straub & Christian):

- :math:`\mathbf{s}_i = \mathbf{o}_i - \mathbf{r}` (eq. 14), :math:`\mathbf{e}_{iI} = \mathbf{s}_i/\|\mathbf{s}_i\|`
  (eq. 15), measurement :math:`\mathbf{h}(\mathbf{x}) = \mathbf{T}_C^I\mathbf{e}_{iI}` (eq. 16), with
  :math:`\mathbf{T}_C^I` (``T_cam_from_inertial``) from the star tracker.
- Sensitivity (eq. 17): :math:`\mathbf{H}_i = \mathbf{T}_C^I\,\|\mathbf{s}_i\|^{-1}
  [\mathbf{e}_{iI}\mathbf{e}_{iI}^T - I,\; 0]`.
- Unit-vector noise (eq. 18, Shuster's QUEST model): :math:`\mathbf{R}_i = \sigma_\theta^2(I - \mathbf{e}\mathbf{e}^T)`,
  rank 2.
- A star-tracker error :math:`\delta\boldsymbol\theta` (small rotation, per axis σ_att) shared by all the points
  of one image adds :math:`[\mathbf{e}_i\times]\,\delta\boldsymbol\theta` to every LOS; the stacked covariance
  is :math:`\sigma_\theta^2\,\mathrm{blkdiag}(I-\mathbf{e}_i\mathbf{e}_i^T) + \sigma_{att}^2\,GG^T` with
  :math:`G_i = [\mathbf{e}_i\times]`, :math:`G_i G_i^T = I - \mathbf{e}_i\mathbf{e}_i^T`. Its null space is
  spanned by the block vectors :math:`\mathbf{e}_i`, which is also the null space of :math:`HPH^T` because
  :math:`\mathbf{H}_i^T\mathbf{e}_i = 0` (eq. 20).
"""

from __future__ import annotations

import numpy as np

from renderlab.geometry.rotations import skew

__all__ = ["los_predict", "los_jacobian_position", "stacked_measurement_covariance", "skew_batch",
           "perturb_unit_vectors", "small_rotation_matrices"]


def skew_batch(v: np.ndarray) -> np.ndarray:
    """Cross-product matrices [v×] for v (..., 3) → (..., 3, 3) (``renderlab.geometry.rotations.skew``)."""
    return skew(v)


def los_predict(r: np.ndarray, o: np.ndarray, T_cam_from_inertial: np.ndarray):
    """Eqs. 14-16: predicted camera-frame unit LOS to points ``o``.

    Parameters
    ----------
    r : ndarray (N, 3)
        Spacecraft positions (inertial, m).
    o : ndarray (m, 3) or (N, m, 3)
        Landmark (coastline point) positions (inertial, m).
    T_cam_from_inertial : ndarray (3, 3) or (N, 3, 3)

    Returns
    -------
    e_cam : ndarray (N, m, 3)
        Eq. 16.
    e_inertial : ndarray (N, m, 3)
        Eq. 15.
    rho : ndarray (N, m)
        ‖s_i‖ (m).
    """
    s = np.asarray(o, dtype=np.float64) - np.asarray(r, dtype=np.float64)[:, None, :]
    rho = np.sqrt(np.einsum("nmi,nmi->nm", s, s))
    e_i = s / rho[..., None]
    T = np.asarray(T_cam_from_inertial, dtype=np.float64)
    e_c = np.einsum("...ij,...mj->...mi", T, e_i) if T.ndim == 3 else e_i @ T.T
    return e_c, e_i, rho


def los_jacobian_position(e_inertial: np.ndarray, rho: np.ndarray, T_cam_from_inertial: np.ndarray) -> np.ndarray:
    """Eq. 17 (position block): ∂h_i/∂r = T (e eᵀ − I)/ρ, shape (N, m, 3, 3). The velocity block is zero."""
    eeT = e_inertial[..., :, None] * e_inertial[..., None, :]
    A = (eeT - np.eye(3)) / rho[..., None, None]
    T = np.asarray(T_cam_from_inertial, dtype=np.float64)
    if T.ndim == 2:
        return np.einsum("ij,nmjk->nmik", T, A)
    return np.einsum("nij,nmjk->nmik", T, A)


def stacked_measurement_covariance(e_cam: np.ndarray, sigma_theta: float, sigma_att: float = 0.0) -> np.ndarray:
    """Eq. 18 for all points of an image stacked, plus the shared star-tracker term: (N, 3m, 3m)."""
    N, m, _ = e_cam.shape
    P_perp = np.eye(3) - e_cam[..., :, None] * e_cam[..., None, :]          # (N, m, 3, 3)
    R = np.zeros((N, m, 3, m, 3))
    idx = np.arange(m)
    R[:, idx, :, idx, :] = sigma_theta**2 * np.moveaxis(P_perp, 1, 0)
    R = R.reshape(N, 3 * m, 3 * m)
    if sigma_att > 0.0:
        G = skew_batch(e_cam).reshape(N, 3 * m, 3)
        R = R + sigma_att**2 * np.matmul(G, np.swapaxes(G, -1, -2))
    return R


def perturb_unit_vectors(e: np.ndarray, sigma: float, z: np.ndarray) -> np.ndarray:
    """Unit vectors ``e`` (..., 3) tilted by a Gaussian angle: e + σ(z₁ a + z₂ b), renormalised.

    ``a, b`` span the plane ⟂ e; ``z`` (..., 2) are standard normal draws supplied by the caller (so the
    caller's seeded ``Generator`` owns every random number). Covariance to first order: σ²(I − eeᵀ), eq. 18.
    """
    e = np.asarray(e, dtype=np.float64)
    helper = np.where(np.abs(e[..., :1]) < 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    a = np.cross(e, helper)
    a /= np.linalg.norm(a, axis=-1, keepdims=True)
    b = np.cross(e, a)
    out = e + sigma * (z[..., :1] * a + z[..., 1:2] * b)
    return out / np.linalg.norm(out, axis=-1, keepdims=True)


def small_rotation_matrices(dtheta: np.ndarray) -> np.ndarray:
    """Rotation matrices exp([δθ×]) (Rodrigues) for rotation vectors δθ (..., 3) → (..., 3, 3)."""
    dtheta = np.asarray(dtheta, dtype=np.float64)
    ang = np.linalg.norm(dtheta, axis=-1)
    K = skew_batch(dtheta)
    with np.errstate(invalid="ignore", divide="ignore"):
        a = np.where(ang > 1e-12, np.sin(ang) / ang, 1.0 - ang**2 / 6.0)
        b = np.where(ang > 1e-12, (1.0 - np.cos(ang)) / ang**2, 0.5 - ang**2 / 24.0)
    return np.eye(3) + a[..., None, None] * K + b[..., None, None] * np.matmul(K, K)
