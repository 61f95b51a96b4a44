r"""Frames and rotations.

Rotations cross API boundaries as :class:`scipy.spatial.transform.Rotation`; quaternions there are
scalar-last ``(x, y, z, w)``. Matrices are named after what they do: ``T_cam_from_body`` maps body-frame
vectors to the camera frame, and ``R_render_from_cam`` maps camera-frame vectors to the render frame.

The lab camera frame has +z along the boresight, +x toward increasing sample (right in the image) and
+y toward increasing line (down in the image). A camera pose (``R_render_from_cam``, ``position``) maps
``p_render = R_render_from_cam @ p_cam + position``; its inverse is the Retina paper's eq. 1,
:math:`\mathbf{x}_C = \mathbf{T}_C^B(\mathbf{x}_B - \mathbf{t}_B)` with
:math:`\mathbf{T}_C^B = R_{render\_from\_cam}^T` (:func:`to_camera_frame`).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from renderlab.errors import UserError

__all__ = [
    "look_at",
    "quat_xyzw",
    "rotation_from_quat_xyzw",
    "rotation_from_matrix",
    "skew",
    "axis_angle",
    "as_axis_angle",
    "transform_points",
    "invert_transform",
    "to_camera_frame",
    "angle_between",
]


def _vec3(v, name: str) -> np.ndarray:
    a = np.asarray(v, dtype=np.float64)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise UserError(f"{name} must be 3 finite numbers, got {np.asarray(v).tolist()!r}")
    return a


def _as_rotation(R) -> Rotation:
    return R if isinstance(R, Rotation) else Rotation.from_matrix(np.asarray(R, dtype=np.float64))


def look_at(position, target, up=(0.0, 0.0, 1.0)) -> Rotation:
    """Camera attitude that points the boresight from `position` at `target`.

    Parameters
    ----------
    position, target : array_like, shape (3,)
        Camera position and the point to look at, in the render frame.
    up : array_like, shape (3,)
        Render-frame direction that should appear toward the top of the image (toward smaller line).
        Only its component perpendicular to the boresight matters.

    Returns
    -------
    Rotation
        ``R_render_from_cam``: columns are the camera +x (right), +y (down), +z (boresight) axes
        expressed in the render frame. ``+x = boresight x up`` (normalized).

    Raises
    ------
    UserError
        If position == target or `up` is parallel to the boresight.
    """
    position = _vec3(position, "position")
    target = _vec3(target, "target")
    up = _vec3(up, "up")
    z = target - position
    dist = np.linalg.norm(z)
    if not dist > 0.0:
        raise UserError("look_at: target coincides with the camera position")
    z = z / dist
    up_perp = up - np.dot(up, z) * z
    n_up = np.linalg.norm(up_perp)
    if not n_up > 1e-9 * max(np.linalg.norm(up), 1e-300):
        raise UserError(f"look_at: up {up.tolist()} is parallel to the boresight {z.tolist()}")
    y = -up_perp / n_up  # image down
    x = np.cross(y, z)   # right-handed: x = y × z
    return Rotation.from_matrix(np.column_stack([x, y, z]))


def quat_xyzw(R) -> np.ndarray:
    """Scalar-last unit quaternion(s) ``(x, y, z, w)`` of `R`, with ``w >= 0`` (canonical sign).

    Parameters
    ----------
    R : Rotation or array_like (3, 3) / (N, 3, 3)

    Returns
    -------
    ndarray, shape (4,) or (N, 4)
    """
    return _as_rotation(R).as_quat(canonical=True)


def rotation_from_quat_xyzw(q, name: str = "quaternion") -> Rotation:
    """Rotation from scalar-last quaternion(s), normalizing them; validates the input.

    Parameters
    ----------
    q : array_like, shape (4,) or (N, 4)
        ``(x, y, z, w)``; any non-zero finite norm is accepted and normalized.
    name : str
        Name used in error messages (e.g. ``"frames[3].pose.quat_render_from_cam_xyzw"``).

    Raises
    ------
    UserError
        Wrong shape, non-finite entries, or a (near-)zero norm.
    """
    try:
        a = np.asarray(q, dtype=np.float64)
    except (TypeError, ValueError):
        raise UserError(f"{name} must be 4 numbers (x, y, z, w), got {q!r}") from None
    if a.shape[-1:] != (4,) or a.ndim > 2:
        raise UserError(f"{name} must have shape (4,) or (N, 4) as (x, y, z, w), got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise UserError(f"{name} must be finite, got {a.tolist()!r}")
    norm = np.linalg.norm(a, axis=-1)
    if np.any(norm < 1e-12):
        raise UserError(f"{name} has zero norm: {a.tolist()!r}")
    return Rotation.from_quat(a / norm[..., None])


def rotation_from_matrix(M, name: str = "rotation matrix", atol: float = 1e-6) -> Rotation:
    """Rotation from a 3x3 matrix that must be proper orthonormal to `atol` (then re-orthonormalized).

    Raises
    ------
    UserError
        Wrong shape, non-finite, not orthonormal, or a reflection (det < 0).
    """
    try:
        a = np.asarray(M, dtype=np.float64)
    except (TypeError, ValueError):
        raise UserError(f"{name} must be a 3x3 matrix of numbers") from None
    if a.shape != (3, 3) or not np.all(np.isfinite(a)):
        raise UserError(f"{name} must be a finite 3x3 matrix, got shape {a.shape}")
    if not np.allclose(a.T @ a, np.eye(3), atol=atol) or np.linalg.det(a) < 0:
        raise UserError(f"{name} is not a proper rotation (orthonormal with det +1)")
    return Rotation.from_matrix(a)


def skew(v) -> np.ndarray:
    """Cross-product matrix: ``skew(v) @ w == np.cross(v, w)``.

    Parameters
    ----------
    v : array_like, shape (..., 3)

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    v = np.asarray(v, dtype=np.float64)
    S = np.zeros(v.shape[:-1] + (3, 3))
    S[..., 0, 1], S[..., 0, 2] = -v[..., 2], v[..., 1]
    S[..., 1, 0], S[..., 1, 2] = v[..., 2], -v[..., 0]
    S[..., 2, 0], S[..., 2, 1] = -v[..., 1], v[..., 0]
    return S


def axis_angle(axis, angle_rad: float) -> Rotation:
    """Rotation by `angle_rad` (right-handed) about `axis` (any non-zero length)."""
    axis = _vec3(axis, "axis")
    n = np.linalg.norm(axis)
    if not n > 0.0:
        raise UserError("axis must be non-zero")
    return Rotation.from_rotvec(axis / n * float(angle_rad))


def as_axis_angle(R) -> tuple[np.ndarray, float]:
    """(unit axis, angle in [0, pi]) of a single rotation; the axis is +z for the identity."""
    rv = _as_rotation(R).as_rotvec()
    angle = float(np.linalg.norm(rv))
    axis = rv / angle if angle > 0.0 else np.array([0.0, 0.0, 1.0])
    return axis, angle


def transform_points(R, t, p) -> np.ndarray:
    """Rigid transform ``R @ p + t`` of points (..., 3).

    Parameters
    ----------
    R : Rotation or array_like (3, 3)
        E.g. ``R_render_from_cam``.
    t : array_like, shape (3,)
        E.g. the camera position in the render frame.
    p : array_like, shape (..., 3)
        Points in the source frame.
    """
    p = np.asarray(p, dtype=np.float64)
    M = _as_rotation(R).as_matrix()
    return p @ M.T + np.asarray(t, dtype=np.float64)


def invert_transform(R, t) -> tuple[Rotation, np.ndarray]:
    """Inverse of ``p -> R p + t``: returns ``(R^-1, -R^-1 t)``."""
    Rinv = _as_rotation(R).inv()
    return Rinv, -Rinv.apply(np.asarray(t, dtype=np.float64))


def to_camera_frame(R_render_from_cam, position, p_render) -> np.ndarray:
    """Eq. 1 of the Retina paper: ``p_cam = R_render_from_cam^T (p_render - position)``.

    Parameters
    ----------
    R_render_from_cam : Rotation or array_like (3, 3)
    position : array_like, shape (3,)
        Camera position in the render frame.
    p_render : array_like, shape (..., 3)
    """
    p = np.asarray(p_render, dtype=np.float64) - np.asarray(position, dtype=np.float64)
    return p @ _as_rotation(R_render_from_cam).as_matrix()


def angle_between(a, b) -> np.ndarray:
    """Angle (rad) between vectors (..., 3), robust near 0 and pi (atan2 of |a x b| and a . b)."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1))
