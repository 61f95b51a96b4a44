r"""Rotating-frame dynamics of the descent filter: state, Jacobian, RK4 state-transition matrix, process noise.

State :math:`\mathbf x = [\mathbf r, \mathbf v]` (m, m/s) in the asteroid-fixed frame, which rotates at the
constant angular velocity :math:`\boldsymbol\omega` (rad/s, body frame) with respect to inertial space. With a
known non-gravitational acceleration :math:`\mathbf u` (the accelerometer's, body frame) and the onboard gravity
:math:`\mathbf g(\mathbf r) = -\mu\,\mathbf r/r^3` (a point mass; the truth's field differs, see the study):

.. math::

    \dot{\mathbf r} = \mathbf v,\qquad
    \dot{\mathbf v} = \mathbf g(\mathbf r) - 2\,\boldsymbol\omega\times\mathbf v
                      - \boldsymbol\omega\times(\boldsymbol\omega\times\mathbf r) + \mathbf u   \quad (D1)

(Coriolis and centrifugal terms of a uniformly rotating frame; Scheeres, *Orbital Motion in Strongly Perturbed
Environments*, 2012, eq. 3.1 without the Euler term). Its Jacobian is

.. math::

    F = \begin{bmatrix} 0 & I \\ G(\mathbf r) - W^2 & -2W \end{bmatrix},\quad
    G = \mu\left(\frac{3\,\mathbf r\mathbf r^T}{r^5} - \frac{I}{r^3}\right),\quad W = [\boldsymbol\omega\times]
    \quad (D2)

and the state-transition matrix obeys :math:`\dot\Phi = F\Phi` (D3), integrated with the state by classical RK4
on steps of at most ``max_step_s``. Process noise: white unmodelled acceleration of PSD ``q`` (m²/s³) per axis,
:math:`Q_q = q\begin{bmatrix}\Delta^3/3 & \Delta^2/2\\ \Delta^2/2 & \Delta\end{bmatrix}` (D4), and the
accelerometer's error held over its sample interval Δ (zero-order hold, σ_u m/s² per axis),
:math:`Q_u = \sigma_u^2\begin{bmatrix}\Delta^4/4 & \Delta^3/2\\ \Delta^3/2 & \Delta^2\end{bmatrix}` (D5)
(Bar-Shalom, Li & Kirubarajan, *Estimation with Applications to Tracking and Navigation*, 2001, eqs. 6.2.2-12
and 6.3.2-4). Pure numpy.
"""

from __future__ import annotations

import numpy as np


def skew(w: np.ndarray) -> np.ndarray:
    """[w×] (3, 3)."""
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def point_mass(r: np.ndarray, gm: float) -> tuple[np.ndarray, np.ndarray]:
    """Acceleration −μ r/|r|³ and its gradient G (eq. D2) at r (3,)."""
    if gm == 0.0:
        return np.zeros(3), np.zeros((3, 3))
    rn = float(np.linalg.norm(r))
    return -gm * r / rn**3, gm * (3.0 * np.outer(r, r) / rn**5 - np.eye(3) / rn**3)


def derivative(x: np.ndarray, gm: float, omega: np.ndarray, u: np.ndarray) -> np.ndarray:
    """ẋ of eq. D1 for one state (6,)."""
    W = skew(omega)
    r, v = x[:3], x[3:]
    g, _ = point_mass(r, gm)
    return np.concatenate([v, g - 2.0 * (W @ v) - W @ (W @ r) + u])


def jacobian(r: np.ndarray, gm: float, omega: np.ndarray) -> np.ndarray:
    """F of eq. D2 (6, 6)."""
    W = skew(omega)
    F = np.zeros((6, 6))
    F[:3, 3:] = np.eye(3)
    F[3:, :3] = point_mass(r, gm)[1] - W @ W
    F[3:, 3:] = -2.0 * W
    return F


def propagate(x: np.ndarray, dt: float, gm: float, omega: np.ndarray, u: np.ndarray,
              max_step_s: float) -> tuple[np.ndarray, np.ndarray]:
    """State and STM after ``dt`` s (RK4 on eqs. D1 and D3, ⌈|dt|/max_step_s⌉ equal steps)."""
    n = max(1, int(np.ceil(abs(dt) / max_step_s - 1e-12)))
    h = dt / n
    x = np.array(x, float)
    phi = np.eye(6)

    W = skew(omega)
    W2 = W @ W
    F = np.zeros((6, 6))
    F[:3, 3:] = np.eye(3)
    F[3:, 3:] = -2.0 * W

    def f(xx, pp):   # eqs. D1 and D3 (the same terms as derivative() and jacobian(), without re-building W)
        r, v = xx[:3], xx[3:]
        g, G = point_mass(r, gm)
        F[3:, :3] = G - W2
        return np.concatenate([v, g - 2.0 * (W @ v) - W2 @ r + u]), F @ pp

    for _ in range(n):
        k1, m1 = f(x, phi)
        k2, m2 = f(x + 0.5 * h * k1, phi + 0.5 * h * m1)
        k3, m3 = f(x + 0.5 * h * k2, phi + 0.5 * h * m2)
        k4, m4 = f(x + h * k3, phi + h * m3)
        x = x + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
        phi = phi + h / 6.0 * (m1 + 2 * m2 + 2 * m3 + m4)
    return x, phi


def white_acceleration_q(dt: float, q: float) -> np.ndarray:
    """Q of eq. D4 (6, 6) for PSD ``q`` m²/s³ per axis."""
    d = abs(dt)
    I3 = np.eye(3)
    return q * np.block([[d**3 / 3.0 * I3, d**2 / 2.0 * I3], [d**2 / 2.0 * I3, d * I3]])


def held_input_q(dt: float, sigma_u: float) -> np.ndarray:
    """Q of eq. D5 (6, 6): an input error of σ_u m/s² per axis held over ``dt``."""
    d = abs(dt)
    I3 = np.eye(3)
    return sigma_u**2 * np.block([[d**4 / 4.0 * I3, d**3 / 2.0 * I3], [d**3 / 2.0 * I3, d**2 * I3]])
