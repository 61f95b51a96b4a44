"""Limb cones and image conics of ellipsoids seen by a pinhole: pure numpy, shared by truth and estimators.

An ellipsoid with centre ``r`` (camera frame, m) and shape matrix ``A`` (camera frame; surface points ``p`` obey
``(p − r)ᵀ A (p − r) = 1``) is seen from the camera centre inside its *tangent cone*. A ray ``x`` (camera frame, any
length) meets the surface where ``(t x − r)ᵀ A (t x − r) = 1``; it grazes it when the discriminant of this quadratic
in ``t`` vanishes, which gives the cone (J. A. Christian, "Accurate planetary limb localization for image-based
spacecraft navigation", J. Spacecraft Rockets 54(3), 2017, doi:10.2514/1.A33692)::

    xᵀ M x = 0,   M = A r rᵀ A − (rᵀ A r − 1) A                                                         (1)

with ``xᵀ M x > 0`` for rays that hit the body. In pixels ``u = K x / z`` (the pinhole map, no distortion) the limb
is the conic ``uᵀ C u = 0`` with ``C = K⁻ᵀ M K⁻¹`` (2). Its centre, semi-axes and orientation follow from
``C = [[Q, b], [bᵀ, c]]``: centre ``u₀ = −Q⁻¹ b`` (3); with ``f₀ = c + bᵀ u₀``, the semi-axes are ``√(−f₀/λᵢ)`` for the
eigenvalues ``λᵢ`` of ``Q`` (4), the major axis along the eigenvector of the smaller ``|λ|``.

Off the boresight the centre of the limb conic is *not* the projection of the body centre: a sphere at angle ``α``
from the boresight with angular radius ``θ`` has its conic centre at ``f·sin α cos α / (cos²α − sin²θ)`` from the
principal point, its projected centre at ``f·tan α``.
"""

from __future__ import annotations

import numpy as np


def shape_matrix(semi_axes, R_frame_from_principal=None) -> np.ndarray:
    """``A = R diag(1/a², 1/b², 1/c²) Rᵀ``: the ellipsoid ``pᵀ A p = 1`` in the frame ``R`` maps principal axes to."""
    d = np.diag(1.0 / np.asarray(semi_axes, float) ** 2)
    R = np.eye(3) if R_frame_from_principal is None else np.asarray(R_frame_from_principal, float)
    return R @ d @ R.T


def limb_cone(A_cam: np.ndarray, r_cam: np.ndarray) -> np.ndarray:
    """Eq. 1: the tangent cone ``M`` (3, 3) of the ellipsoid ``A_cam`` centred at ``r_cam`` (camera frame)."""
    A = np.asarray(A_cam, float)
    r = np.asarray(r_cam, float)
    Ar = A @ r
    return np.outer(Ar, Ar) - (r @ Ar - 1.0) * A


def cone_to_pixels(M: np.ndarray, K: np.ndarray) -> np.ndarray:
    """Eq. 2: the image conic ``C = K⁻ᵀ M K⁻¹`` in homogeneous pixels ``(s, l, 1)``."""
    Ki = np.linalg.inv(np.asarray(K, float))
    return Ki.T @ np.asarray(M, float) @ Ki


def pixels_to_cone(C: np.ndarray, K: np.ndarray) -> np.ndarray:
    """Inverse of eq. 2: ``M = Kᵀ C K``."""
    K = np.asarray(K, float)
    return K.T @ np.asarray(C, float) @ K


def ellipse_params(C: np.ndarray) -> tuple[np.ndarray, float, float, float] | None:
    """Eqs. 3–4: ``(centre (2,), a, b, angle)`` of the conic ``C`` or None when it is not a real ellipse.

    ``a ≥ b`` are the semi-axes (px), ``angle`` (rad, in (−π/2, π/2]) the direction of the major axis from +s toward
    +l.
    """
    C = 0.5 * (np.asarray(C, float) + np.asarray(C, float).T)
    Q, b, c = C[:2, :2], C[:2, 2], C[2, 2]
    if not np.all(np.isfinite(C)):
        return None
    det = np.linalg.det(Q)
    if not det > 1e-300 * max(1.0, np.abs(Q).max() ** 2):
        return None  # a parabola, hyperbola or degenerate conic
    u0 = -np.linalg.solve(Q, b)
    f0 = c + b @ u0
    lam, vec = np.linalg.eigh(Q)
    if not (np.all(lam > 0) and f0 < 0) and not (np.all(lam < 0) and f0 > 0):
        return None  # imaginary ellipse
    ax = np.sqrt(-f0 / lam)
    k_major = int(np.argmax(ax))
    v = vec[:, k_major]
    angle = float(np.arctan2(v[1], v[0]))
    if angle <= -np.pi / 2:
        angle += np.pi
    elif angle > np.pi / 2:
        angle -= np.pi
    return u0, float(ax.max()), float(ax.min()), angle


def ellipse_to_conic(centre, a: float, b: float, angle: float) -> np.ndarray:
    """The conic (3, 3) of the ellipse with ``centre`` (2,), semi-axes ``a``, ``b`` and major-axis ``angle``, scaled
    so that it is negative inside (``uᵀ C u < 0``)."""
    c, s = np.cos(angle), np.sin(angle)
    R = np.array([[c, -s], [s, c]])
    Q = R @ np.diag([1.0 / a**2, 1.0 / b**2]) @ R.T
    u0 = np.asarray(centre, float)
    out = np.empty((3, 3))
    out[:2, :2] = Q
    out[:2, 2] = out[2, :2] = -Q @ u0
    out[2, 2] = u0 @ Q @ u0 - 1.0
    return out


def conic_distance(C: np.ndarray, points: np.ndarray) -> np.ndarray:
    """First-order (Sampson) distance (px) of ``points`` (n, 2) from the conic ``C``: ``|uᵀCu| / |∇(uᵀCu)|``."""
    P = np.column_stack([np.asarray(points, float), np.ones(len(points))])
    Cu = P @ np.asarray(C, float)
    val = np.einsum("ij,ij->i", Cu, P)
    grad = 2.0 * Cu[:, :2]
    return val / np.linalg.norm(grad, axis=1)
