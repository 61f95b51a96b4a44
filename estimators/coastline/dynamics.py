r"""Onboard orbit model of the coastline EKF: two-body dynamics, its Jacobian, and the state
transition matrix, vectorised over a leading run axis.

Theory (Straub & Christian, coastline-ekf paper):

- State :math:`\mathbf{x} = [\mathbf{r}, \dot{\mathbf{r}}]` (eq. 11), inertial (ECI), SI units.
- Two-body motion :math:`\ddot{\mathbf{r}} = -\mu\,\mathbf{r}/\|\mathbf{r}\|^3` (eq. 10), i.e.
  :math:`\mathbf{f}(\mathbf{x}) = [\dot{\mathbf{r}}, -\mu\mathbf{r}/\|\mathbf{r}\|^3]` (eq. 12).
- Its Jacobian (eq. 13): :math:`\mathbf{F} = [[0, I], [G, 0]]` with the gravity gradient
  :math:`G = -\mu/r^3\,(I - 3\,\hat{\mathbf{r}}\hat{\mathbf{r}}^T)`. (The paper prints the second term as
  :math:`-\mu/r^5\,\mathbf{r}\mathbf{r}^T`; the derivative of eq. 12 is :math:`+3\mu/r^5\,\mathbf{r}\mathbf{r}^T`,
  which is what this module uses — the finite-difference test pins it.)
- Covariance propagation, eq. 3 :math:`\dot P = FP + PF^T + Q`, is done in its equivalent discrete form
  :math:`P^- = \Phi P \Phi^T + Q_d` with the state transition matrix :math:`\dot\Phi = F\Phi`,
  :math:`\Phi(t_0) = I`, integrated together with the state by fixed-step RK4.
- :math:`Q_d` for continuous white acceleration noise of spectral density q (m²/s³):
  :math:`q\,[[\Delta t^3/3\,I, \Delta t^2/2\,I], [\Delta t^2/2\,I, \Delta t\,I]]`.

This is the *onboard* model; the truth side has its own propagator (the tests compare both with
scipy's ``solve_ivp``).
"""

from __future__ import annotations

import math

import numpy as np

MU_EARTH = 3.986004418e14
"""Earth's gravitational parameter (m³/s², WGS-84/EGM-96)."""

__all__ = ["MU_EARTH", "two_body_rhs", "gravity_gradient", "dynamics_jacobian", "propagate_state_stm",
           "white_acceleration_qd"]


def two_body_rhs(x: np.ndarray, mu: float = MU_EARTH) -> np.ndarray:
    """Eq. 12: time derivative of the state(s) ``x`` (..., 6) under two-body gravity."""
    x = np.asarray(x, dtype=np.float64)
    r = x[..., :3]
    rn = np.sqrt(np.einsum("...i,...i->...", r, r))
    acc = -mu * r / (rn**3)[..., None]
    return np.concatenate([x[..., 3:], acc], axis=-1)


def gravity_gradient(r: np.ndarray, mu: float = MU_EARTH) -> np.ndarray:
    """:math:`\\partial\\ddot{\\mathbf r}/\\partial\\mathbf r` (lower-left block of eq. 13), shape (..., 3, 3)."""
    r = np.asarray(r, dtype=np.float64)
    rn = np.sqrt(np.einsum("...i,...i->...", r, r))
    rr = r[..., :, None] * r[..., None, :]
    return (-mu / rn**3)[..., None, None] * np.eye(3) + (3.0 * mu / rn**5)[..., None, None] * rr


def dynamics_jacobian(x: np.ndarray, mu: float = MU_EARTH) -> np.ndarray:
    """Eq. 13: F = ∂f/∂x at ``x`` (..., 6) → (..., 6, 6)."""
    x = np.asarray(x, dtype=np.float64)
    F = np.zeros(x.shape[:-1] + (6, 6))
    F[..., :3, 3:] = np.eye(3)
    F[..., 3:, :3] = gravity_gradient(x[..., :3], mu)
    return F


def _rhs_state_stm(x: np.ndarray, phi: np.ndarray, mu: float) -> tuple[np.ndarray, np.ndarray]:
    """ẋ = f(x) and Φ̇ = F(x) Φ, using the block structure of F: the lower rows are
    G Φ_r = a Φ_r + b r (rᵀ Φ_r) with a = −μ/r³, b = 3μ/r⁵ (no 6x6 product)."""
    r = x[..., :3]
    rn2 = np.einsum("...i,...i->...", r, r)
    rn = np.sqrt(rn2)
    a = -mu / (rn2 * rn)
    b = -3.0 * a / rn2
    xd = np.concatenate([x[..., 3:], a[..., None] * r], axis=-1)
    top = phi[..., :3, :]
    rt = np.einsum("...i,...ij->...j", r, top)
    phid = np.empty_like(phi)
    phid[..., :3, :] = phi[..., 3:, :]
    phid[..., 3:, :] = a[..., None, None] * top + (b[..., None] * rt)[..., None, :] * r[..., :, None]
    return xd, phid


def propagate_state_stm(x: np.ndarray, dt: float, mu: float = MU_EARTH,
                        max_step_s: float = 5.0) -> tuple[np.ndarray, np.ndarray]:
    """Propagate states ``x`` (..., 6) by ``dt`` seconds with fixed-step RK4 on [x, Φ].

    Parameters
    ----------
    x : ndarray (..., 6)
        Inertial position (m) and velocity (m/s).
    dt : float
        Propagation interval (s); may be 0 or negative.
    mu : float
        Gravitational parameter (m³/s²).
    max_step_s : float
        Largest RK4 step; the interval is split into ``ceil(|dt|/max_step_s)`` equal steps.

    Returns
    -------
    x_new : ndarray (..., 6)
    phi : ndarray (..., 6, 6)
        State transition matrix Φ(t+dt, t) = ∂x_new/∂x.
    """
    x = np.array(x, dtype=np.float64)
    phi = np.broadcast_to(np.eye(6), x.shape[:-1] + (6, 6)).copy()
    if dt == 0.0:
        return x, phi
    n = max(1, int(math.ceil(abs(dt) / max_step_s)))
    h = dt / n
    for _ in range(n):
        k1x, k1p = _rhs_state_stm(x, phi, mu)
        k2x, k2p = _rhs_state_stm(x + 0.5 * h * k1x, phi + 0.5 * h * k1p, mu)
        k3x, k3p = _rhs_state_stm(x + 0.5 * h * k2x, phi + 0.5 * h * k2p, mu)
        k4x, k4p = _rhs_state_stm(x + h * k3x, phi + h * k3p, mu)
        x = x + (h / 6.0) * (k1x + 2.0 * k2x + 2.0 * k3x + k4x)
        phi = phi + (h / 6.0) * (k1p + 2.0 * k2p + 2.0 * k3p + k4p)
    return x, phi


def white_acceleration_qd(dt: float, q_acc: float) -> np.ndarray:
    """Discrete process noise (6, 6) of continuous white acceleration noise with PSD ``q_acc`` (m²/s³)."""
    I3 = np.eye(3)
    dt = abs(dt)
    return q_acc * np.block([[dt**3 / 3.0 * I3, dt**2 / 2.0 * I3], [dt**2 / 2.0 * I3, dt * I3]])
