r"""OpenCV's full distortion model: rational radial, tangential, thin prism and sensor tilt (model ``opencv``).

The model of ``cv2.projectPoints`` with a 14-coefficient distortion vector
``(k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4, tau_x, tau_y)`` (the coefficient keys, in that order; missing
keys are 0, so 8- and 12-coefficient vectors are the same model with zero tail). On normalized coordinates
:math:`(x, y)` with :math:`r^2 = x^2 + y^2`:

.. math::

    R &= \frac{1 + k_1 r^2 + k_2 r^4 + k_3 r^6}{1 + k_4 r^2 + k_5 r^4 + k_6 r^6}, \\
    x_0 &= x R + 2 p_1 x y + p_2 (r^2 + 2x^2) + s_1 r^2 + s_2 r^4, \\
    y_0 &= y R + p_1 (r^2 + 2y^2) + 2 p_2 x y + s_3 r^2 + s_4 r^4,

and the tilted sensor maps :math:`(x_0, y_0)` by the homography :math:`M(\tau_x, \tau_y)` of
:func:`tilt_matrix`: :math:`(x_d, y_d) = (v_0, v_1) / v_2` with :math:`v = M (x_0, y_0, 1)^T`. With all of
``k4 .. tau_y`` zero this is exactly the ``brown`` model. The tilt angles are in radians.

The Newton inverse is the generic one of :func:`renderlab.geometry.distortion.undistort`, fed by
:func:`distort_xy` and :func:`jacobian_xy`; beyond a pole of the rational denominator or a fold the
Jacobian's determinant is not positive and the camera refuses the point.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

__all__ = ["KEYS", "tilt_matrix", "distort_xy", "jacobian_xy"]

#: Coefficient names, in OpenCV's distortion-vector order.
KEYS: tuple[str, ...] = ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6", "s1", "s2", "s3", "s4", "tau_x", "tau_y")


def tilt_matrix(tau_x: float, tau_y: float) -> np.ndarray:
    """OpenCV's sensor-tilt homography (``computeTiltProjectionMatrix``).

    Parameters
    ----------
    tau_x, tau_y : float
        Tilt of the sensor about the x and y axes (radians).

    Returns
    -------
    ndarray, shape (3, 3)
        ``M = P_z(R) R`` with ``R = R_y(tau_y) R_x(tau_x)`` and ``P_z`` the projection back onto the
        untilted image plane; the identity for zero tilt.
    """
    cx, sx, cy, sy = np.cos(tau_x), np.sin(tau_x), np.cos(tau_y), np.sin(tau_y)
    rot_x = np.array([[1.0, 0.0, 0.0], [0.0, cx, sx], [0.0, -sx, cx]])
    rot_y = np.array([[cy, 0.0, -sy], [0.0, 1.0, 0.0], [sy, 0.0, cy]])
    rot = rot_y @ rot_x
    proj_z = np.array([[rot[2, 2], 0.0, -rot[0, 2]], [0.0, rot[2, 2], -rot[1, 2]], [0.0, 0.0, 1.0]])
    return proj_z @ rot


def _tilted(c: Mapping[str, float]) -> bool:
    return c["tau_x"] != 0.0 or c["tau_y"] != 0.0


def _finite_or_nan(*arrays: np.ndarray) -> tuple[np.ndarray, ...]:
    """The arrays with inf (at a pole of the rational denominator) replaced by NaN, which propagates quietly."""
    return tuple(np.where(np.isfinite(a), a, np.nan) for a in arrays)


def _untilted(c: Mapping[str, float], x: np.ndarray, y: np.ndarray):
    """(x0, y0) before the tilt, and the pieces the Jacobian reuses: R, dR/d(r²), r² (call under np.errstate)."""
    x2, y2, xy = x * x, y * y, x * y
    r2 = x2 + y2
    num = 1.0 + r2 * (c["k1"] + r2 * (c["k2"] + r2 * c["k3"]))
    den = 1.0 + r2 * (c["k4"] + r2 * (c["k5"] + r2 * c["k6"]))
    dnum = c["k1"] + r2 * (2.0 * c["k2"] + 3.0 * c["k3"] * r2)
    dden = c["k4"] + r2 * (2.0 * c["k5"] + 3.0 * c["k6"] * r2)
    radial = num / den
    dradial = (dnum * den - num * dden) / (den * den)
    p1, p2 = c["p1"], c["p2"]
    x0 = x * radial + 2.0 * p1 * xy + p2 * (r2 + 2.0 * x2) + r2 * (c["s1"] + c["s2"] * r2)
    y0 = y * radial + p1 * (r2 + 2.0 * y2) + 2.0 * p2 * xy + r2 * (c["s3"] + c["s4"] * r2)
    return x0, y0, radial, dradial, r2


def _apply_tilt(m: np.ndarray, x0: np.ndarray, y0: np.ndarray):
    """(xd, yd, 1/v2) of the homography m applied to (x0, y0, 1); OpenCV uses 1 where v2 == 0."""
    v0 = m[0, 0] * x0 + m[0, 1] * y0 + m[0, 2]
    v1 = m[1, 0] * x0 + m[1, 1] * y0 + m[1, 2]
    v2 = m[2, 0] * x0 + m[2, 1] * y0 + m[2, 2]
    inv = np.where(v2 != 0.0, 1.0 / np.where(v2 != 0.0, v2, 1.0), 1.0)
    return v0 * inv, v1 * inv, inv


def distort_xy(c: Mapping[str, float], x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distorted normalized coordinates (xd, yd) of (x, y).

    Parameters
    ----------
    c : mapping
        Every coefficient of :data:`KEYS`.
    x, y : ndarray
        Undistorted normalized coordinates (same shape).

    Returns
    -------
    tuple of ndarray
        ``(xd, yd)``, the shape of `x`.
    """
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        x0, y0, _, _, _ = _untilted(c, x, y)
        if not _tilted(c):
            return _finite_or_nan(x0, y0)
        xd, yd, _ = _apply_tilt(tilt_matrix(c["tau_x"], c["tau_y"]), x0, y0)
    return _finite_or_nan(xd, yd)


def jacobian_xy(c: Mapping[str, float], x: np.ndarray, y: np.ndarray):
    """Analytic Jacobian of :func:`distort_xy`.

    Parameters
    ----------
    c : mapping
        Every coefficient of :data:`KEYS`.
    x, y : ndarray
        Undistorted normalized coordinates.

    Returns
    -------
    tuple of ndarray
        ``(J00, J01, J10, J11)`` with ``J[i][j] = d(xd, yd)[i] / d(x, y)[j]``.
    """
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        return _finite_or_nan(*_jacobian(c, x, y))


def _jacobian(c: Mapping[str, float], x: np.ndarray, y: np.ndarray):
    x0, y0, radial, dradial, r2 = _untilted(c, x, y)
    p1, p2 = c["p1"], c["p2"]
    prism_x = 2.0 * (c["s1"] + 2.0 * c["s2"] * r2)  # d(s1 r² + s2 r⁴)/dx = prism_x · x
    prism_y = 2.0 * (c["s3"] + 2.0 * c["s4"] * r2)
    off = 2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y
    j00 = radial + 2.0 * x * x * dradial + 2.0 * p1 * y + 6.0 * p2 * x + prism_x * x
    j01 = off + prism_x * y
    j10 = off + prism_y * x
    j11 = radial + 2.0 * y * y * dradial + 6.0 * p1 * y + 2.0 * p2 * x + prism_y * y
    if not _tilted(c):
        return j00, j01, j10, j11
    m = tilt_matrix(c["tau_x"], c["tau_y"])
    xd, yd, inv = _apply_tilt(m, x0, y0)
    # d(v0/v2, v1/v2)/d(x0, y0) = ([M00 M01; M10 M11] - (xd, yd) [M20 M21]) / v2
    t00, t01 = (m[0, 0] - xd * m[2, 0]) * inv, (m[0, 1] - xd * m[2, 1]) * inv
    t10, t11 = (m[1, 0] - yd * m[2, 0]) * inv, (m[1, 1] - yd * m[2, 1]) * inv
    return (t00 * j00 + t01 * j10, t00 * j01 + t01 * j11,
            t10 * j00 + t11 * j10, t10 * j01 + t11 * j11)
