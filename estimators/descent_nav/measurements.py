r"""Measurement models of the descent filter: predicted value, Jacobian and covariance per measurement kind.

* ``"pixel"`` — landmark pixel coordinates :math:`\mathbf z_i = (s_i, l_i)` of known maplet centres
  :math:`\mathbf p_i` (body frame) through the believed camera model and the star-tracker attitude
  :math:`T = R_{body\leftarrow cam}`: :math:`\mathbf h_i(\mathbf r) = \pi(T^T(\mathbf p_i - \mathbf r))`
  (Wright et al., eqs. 1–4: eq. 1 the camera frame, eqs. 2–4 the projection and pixel map), with
  :math:`\partial\mathbf h_i/\partial\mathbf r = -J_\pi T^T` (M1) and :math:`\partial\mathbf h_i/\partial\mathbf v = 0`.
  The star tracker's error :math:`\delta\boldsymbol\theta` (camera axes, :math:`T_{true} = T\,\exp([\delta\boldsymbol
  \theta\times])`) moves every landmark of the image together: :math:`\partial\mathbf h_i/\partial\delta\boldsymbol
  \theta = J_\pi[\mathbf x_{c,i}\times]` (M2), so the image's covariance is
  :math:`R = \sigma_{px}^2 I_{2k} + J_\theta\,\sigma_{att}^2 I_3\,J_\theta^T` (M3) (:func:`pixel_covariance`).
* ``"los"`` — unit line-of-sight vectors in the camera frame (the lab's coastline kind, Straub & Christian eq. 18
  covariance, rank 2 per LOS). Each LOS is reduced to 2 dof on an orthonormal basis :math:`B_i \perp \mathbf z_i`:
  :math:`B_i\mathbf z_i` vs :math:`B_i T\mathbf e_i(\mathbf r)`, :math:`\partial\mathbf e_i/\partial\mathbf r =
  -(I - \mathbf e_i\mathbf e_i^T)/\rho_i` (M4), covariance :math:`B R B^T`.
* ``"position"`` — a position fix, :math:`H = [I\;0]` (M5).

Each model returns the innovation ν, H, R and the index groups of the individual landmarks (for the gate).
"""

from __future__ import annotations

import numpy as np

from renderlab.errors import UserError

NEEDS = {"pixel": ("points_body_m", "R_body_from_cam", "camera"), "los": ("points_eci_m", "R_cam_from_eci"),
         "position": ()}


def _context(kind: str, context: dict, who: str) -> dict:
    if kind not in NEEDS:
        raise UserError(f"{who}: measurement kind {kind!r} is not supported (one of {', '.join(NEEDS)})")
    missing = [k for k in NEEDS[kind] if k not in (context or {})]
    if missing:
        raise UserError(f"{who}: a {kind!r} measurement needs context key {missing[0]!r} "
                        f"(has {', '.join(sorted(context or {})) or 'none'})")
    return context


def _points(ctx: dict, key: str, who: str) -> np.ndarray:
    p = np.asarray(ctx[key], float)
    if p.ndim != 2 or p.shape[1] != 3 or not np.all(np.isfinite(p)):
        raise UserError(f"{who}: context {key!r} must be a finite (k, 3) array, got shape {p.shape}")
    return p


def pixel_model(x: np.ndarray, z: np.ndarray, ctx: dict, who: str):
    """ν, H, groups of the ``"pixel"`` kind (eq. M1)."""
    p = _points(ctx, "points_body_m", who)
    T = np.asarray(ctx["R_body_from_cam"], float)
    cam = ctx["camera"]
    xc = (p - x[:3]) @ T
    h = cam.project(xc)
    Jp = cam.project_jacobian(xc)                      # (k, 2, 3)
    H = np.zeros((2 * len(p), 6))
    H[:, :3] = (-Jp @ T.T).reshape(-1, 3)
    return z - h.reshape(-1), H, [np.arange(2 * i, 2 * i + 2) for i in range(len(p))]


def pixel_covariance(camera, points_body_m, position_m, R_body_from_cam, sigma_px: float,
                     sigma_att_rad: float) -> np.ndarray:
    """R of eq. M3 (2k, 2k): independent pixel noise (σ_px: one value, or one per landmark (k,)) plus the
    star-tracker error common to the image."""
    xc = (np.asarray(points_body_m, float) - np.asarray(position_m, float)) @ np.asarray(R_body_from_cam, float)
    Jp = camera.project_jacobian(xc)                  # (k, 2, 3)
    sk = np.zeros((len(xc), 3, 3))
    sk[:, 0, 1], sk[:, 0, 2], sk[:, 1, 2] = -xc[:, 2], xc[:, 1], -xc[:, 0]
    sk[:, 1, 0], sk[:, 2, 0], sk[:, 2, 1] = xc[:, 2], -xc[:, 1], xc[:, 0]
    Jt = (Jp @ sk).reshape(-1, 3)                     # eq. M2
    var = np.repeat(np.broadcast_to(np.asarray(sigma_px, float) ** 2, (len(xc),)), 2)
    return np.diag(var) + sigma_att_rad**2 * Jt @ Jt.T


def _basis(e: np.ndarray) -> np.ndarray:
    """Orthonormal (k, 2, 3) bases perpendicular to unit vectors e (k, 3)."""
    a = np.where(np.abs(e[:, :1]) < 0.9, np.array([[1.0, 0, 0]]), np.array([[0, 1.0, 0]]))
    b1 = np.cross(e, a)
    b1 /= np.linalg.norm(b1, axis=1, keepdims=True)
    return np.stack([b1, np.cross(e, b1)], axis=1)


def los_model(x: np.ndarray, z: np.ndarray, R: np.ndarray, ctx: dict, who: str):
    """ν, H, R, groups of the ``"los"`` kind reduced to 2 dof per LOS (eq. M4)."""
    p = _points(ctx, "points_eci_m", who)
    T = np.asarray(ctx["R_cam_from_eci"], float)
    k = len(p)
    zc = z.reshape(k, 3)
    B = _basis(zc / np.linalg.norm(zc, axis=1, keepdims=True))
    d = p - x[:3]
    rho = np.linalg.norm(d, axis=1)
    e = d / rho[:, None]
    de = -(np.eye(3)[None] - e[:, :, None] * e[:, None, :]) / rho[:, None, None]
    H = np.zeros((2 * k, 6))
    H[:, :3] = np.einsum("kij,jl,klm->kim", B, T, de).reshape(-1, 3)
    nu = np.einsum("kij,kj->ki", B, zc - e @ T.T).reshape(-1)
    Bb = np.zeros((2 * k, 3 * k))
    for i in range(k):
        Bb[2 * i:2 * i + 2, 3 * i:3 * i + 3] = B[i]
    return nu, H, Bb @ R @ Bb.T, [np.arange(2 * i, 2 * i + 2) for i in range(k)]


def model(kind: str, x: np.ndarray, z: np.ndarray, R: np.ndarray, context: dict, who: str):
    """(ν, H, R, groups) of a measurement of ``kind`` at state ``x`` (module docstring)."""
    ctx = _context(kind, context, who)
    if kind == "pixel":
        nu, H, groups = pixel_model(x, z, ctx, who)
        return nu, H, R, groups
    if kind == "los":
        return los_model(x, z, R, ctx, who)
    H = np.hstack([np.eye(3), np.zeros((3, 3))])
    return z - x[:3], H, R, [np.arange(3)]
