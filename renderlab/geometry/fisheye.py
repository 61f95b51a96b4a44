r"""Kannala–Brandt fisheye distortion exactly as OpenCV's ``cv2.fisheye`` (model ``kannala_brandt``).

The model (keys ``k1 .. k4``) acts on the angle from the boresight rather than on the gnomonic radius: for
normalized coordinates :math:`\mathbf{u} = (x, y)` with :math:`r = |\mathbf{u}|` and :math:`\theta = \arctan r`,

.. math::

    \theta_d = \theta (1 + k_1 \theta^2 + k_2 \theta^4 + k_3 \theta^6 + k_4 \theta^8), \qquad
    \mathbf{u}_d = \frac{\theta_d}{r} \mathbf{u},

(``cv2.fisheye.projectPoints``; with all ``k`` zero it is the equidistant projection
:math:`r_d = \theta`). OpenCV's skew ``alpha`` is the camera's ``skew / fx``. The map is radial,
:math:`\mathbf{u}_d = g(r)\,\mathbf{u}/r` with :math:`g(r) = \theta_d(\arctan r)`, so its Jacobian is

.. math::

    J = \frac{g}{r} I + \Big(g' - \frac{g}{r}\Big) \hat{\mathbf{u}} \hat{\mathbf{u}}^T, \qquad
    g'(r) = \frac{1 + 3k_1\theta^2 + 5k_2\theta^4 + 7k_3\theta^6 + 9k_4\theta^8}{1 + r^2},

with :math:`\hat{\mathbf{u}} = \mathbf{u}/r`; both terms are bounded, and at :math:`r \to 0` the limit is
the identity. Points behind the camera (``z <= 0``, :math:`\theta \ge 90°`) are outside the gnomonic
pipeline of :class:`~renderlab.geometry.camera.CameraModel`; a fold (:math:`d\theta_d/d\theta \le 0`) limits
the field as for the other models.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

__all__ = ["KEYS", "distort_xy", "jacobian_xy"]

#: Coefficient names (OpenCV's fisheye distortion vector order).
KEYS: tuple[str, ...] = ("k1", "k2", "k3", "k4")

_SMALL_R = 1e-8
"""Below this radius OpenCV takes the distortion factor as 1 (its error there is below 1e-16)."""


def _radial(c: Mapping[str, float], x: np.ndarray, y: np.ndarray):
    """r, theta, theta² and the factor g/r = theta_d / r (1 below :data:`_SMALL_R`)."""
    r = np.hypot(x, y)
    theta = np.arctan(r)
    t2 = theta * theta
    theta_d = theta * (1.0 + t2 * (c["k1"] + t2 * (c["k2"] + t2 * (c["k3"] + t2 * c["k4"]))))
    small = r <= _SMALL_R
    factor = np.where(small, 1.0, theta_d / np.where(small, 1.0, r))
    return r, t2, small, factor


def distort_xy(c: Mapping[str, float], x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distorted normalized coordinates (xd, yd) = (theta_d / r) (x, y).

    Parameters
    ----------
    c : mapping
        Coefficients ``k1 .. k4``.
    x, y : ndarray
        Undistorted normalized coordinates (same shape).

    Returns
    -------
    tuple of ndarray
        ``(xd, yd)``, the shape of `x`.
    """
    _, _, _, factor = _radial(c, x, y)
    return x * factor, y * factor


def jacobian_xy(c: Mapping[str, float], x: np.ndarray, y: np.ndarray):
    """Analytic Jacobian of :func:`distort_xy`.

    Parameters
    ----------
    c : mapping
        Coefficients ``k1 .. k4``.
    x, y : ndarray
        Undistorted normalized coordinates.

    Returns
    -------
    tuple of ndarray
        ``(J00, J01, J10, J11)`` with ``J[i][j] = d(xd, yd)[i] / d(x, y)[j]``; the identity below
        :data:`_SMALL_R` (the limit, like OpenCV's factor 1 there).
    """
    r, t2, small, factor = _radial(c, x, y)
    dtheta_d = 1.0 + t2 * (3.0 * c["k1"] + t2 * (5.0 * c["k2"] + t2 * (7.0 * c["k3"] + t2 * 9.0 * c["k4"])))
    g_prime = dtheta_d / (1.0 + r * r)
    inv_r = np.where(small, 0.0, 1.0 / np.where(small, 1.0, r))
    nx, ny = x * inv_r, y * inv_r  # unit vector (0 at the axis, where the outer-product term vanishes)
    excess = np.where(small, 0.0, g_prime - factor)
    off = excess * nx * ny
    return factor + excess * nx * nx, off, off.copy(), factor + excess * ny * ny
