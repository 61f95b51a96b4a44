"""Camera poses in the conventions an engineer brings, turned into the lab's :class:`CameraPose`.

The lab's convention (``docs/architecture.md``): ``p_render = R_render_from_cam · p_cam + position_m``, camera
frame +z boresight, +x toward increasing sample, +y toward increasing line. :func:`camera_pose` accepts

* a :class:`~renderlab.dynamics.camera_paths.CameraPose` (as it is) or a planned
  :class:`~renderlab.render.scene.FrameSpec` (its pose);
* a 4×4 homogeneous matrix ``T_render_from_cam`` (``convention="render_from_cam"``, the default) or
  ``T_cam_from_render`` (``convention="cam_from_render"``, the OpenCV extrinsic [R | t]);
* a mapping with ``position_m`` and one of ``quat_render_from_cam_xyzw`` (the manifest's keys),
  ``quaternion`` + ``order`` (``"xyzw"``, scalar last, SciPy/Eigen-coeffs; or ``"wxyz"``, scalar first,
  the Hamilton order of most GN&C texts), or ``R`` (3×3 matrix); ``convention`` says which way the rotation
  maps (with ``cam_from_render``, ``position_m`` is still the camera centre in the render frame);
* a ``(position_m, R_render_from_cam)`` pair.

Every input is validated (finite, unit-normalisable quaternion, proper rotation) with a one-line
:class:`~renderlab.errors.UserError` naming the field.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from scipy.spatial.transform import Rotation

from renderlab.dynamics.camera_paths import CameraPose
from renderlab.errors import UserError
from renderlab.geometry.rotations import rotation_from_matrix, rotation_from_quat_xyzw

CONVENTIONS = ("render_from_cam", "cam_from_render")
ORDERS = ("xyzw", "wxyz")


def _vector(v, name: str) -> np.ndarray:
    try:
        a = np.asarray(v, dtype=np.float64)
    except (TypeError, ValueError):
        raise UserError(f"{name} must be 3 numbers") from None
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise UserError(f"{name} must be 3 finite numbers, got shape {a.shape}")
    return a


def _rotation(d: Mapping, name: str) -> Rotation:
    if "quat_render_from_cam_xyzw" in d:
        return rotation_from_quat_xyzw(d["quat_render_from_cam_xyzw"], f"{name}.quat_render_from_cam_xyzw")
    if "quaternion" in d:
        order = d.get("order")
        if order not in ORDERS:
            raise UserError(f"{name}.order must declare the quaternion order, one of {', '.join(ORDERS)}; "
                            f"got {str(order)[:40]!r}")
        q = d["quaternion"]
        if order == "wxyz" and np.shape(q) == (4,):
            q = [q[1], q[2], q[3], q[0]]  # scalar first → scalar last (validated next)
        return rotation_from_quat_xyzw(q, f"{name}.quaternion")
    if "R" in d:
        return rotation_from_matrix(d["R"], f"{name}.R")
    raise UserError(f"{name} needs a rotation: quat_render_from_cam_xyzw, quaternion (+ order) or R")


def camera_pose(pose, *, time_s: float = 0.0, convention: str | None = None, name: str = "pose") -> CameraPose:
    """The :class:`CameraPose` of ``pose`` in any supported form (module docstring).

    Parameters
    ----------
    pose : CameraPose, FrameSpec, (4, 4) array, mapping or (position_m, R) pair
    time_s : float
        Time of the pose (s) when ``pose`` carries none.
    convention : {"render_from_cam", "cam_from_render"}, optional
        Which way the given rotation (or matrix) maps; a mapping may say it under ``"convention"``.
    name : str
        Name used in error messages.
    """
    if isinstance(pose, CameraPose):
        return pose
    if hasattr(pose, "pose") and isinstance(pose.pose, CameraPose):  # a FrameSpec
        return pose.pose
    if isinstance(pose, Mapping):
        conv = convention or pose.get("convention", "render_from_cam")
        _check_convention(conv, name)
        R = _rotation(pose, name)
        position = _vector(pose.get("position_m"), f"{name}.position_m")
        t = float(pose.get("time_s", time_s))
        return CameraPose(t, position, R.inv() if conv == "cam_from_render" else R, pose.get("epoch_utc"))
    conv = convention or "render_from_cam"
    _check_convention(conv, name)
    if isinstance(pose, (tuple, list)) and len(pose) == 2:
        position = _vector(pose[0], f"{name}[0] (position_m)")
        R = pose[1] if isinstance(pose[1], Rotation) else rotation_from_matrix(pose[1], f"{name}[1] (rotation)")
        return CameraPose(float(time_s), position, R.inv() if conv == "cam_from_render" else R)
    try:
        T = np.asarray(pose, dtype=np.float64)
    except (TypeError, ValueError):
        raise UserError(f"{name}: not a pose ({type(pose).__name__}); see renderlab.pipeline.poses") from None
    if T.shape != (4, 4) or not np.all(np.isfinite(T)) or not np.allclose(T[3], [0, 0, 0, 1]):
        raise UserError(f"{name} must be a finite 4x4 homogeneous matrix (last row 0 0 0 1), got shape {T.shape}")
    R = rotation_from_matrix(T[:3, :3], f"{name}[:3, :3]")
    if conv == "cam_from_render":  # p_cam = R p_render + t  →  centre = −Rᵀ t
        return CameraPose(float(time_s), -(R.inv().apply(T[:3, 3])), R.inv())
    return CameraPose(float(time_s), T[:3, 3].copy(), R)


def _check_convention(conv, name: str) -> None:
    if conv not in CONVENTIONS:
        raise UserError(f"{name}: convention must be one of {', '.join(CONVENTIONS)}, got {str(conv)[:40]!r}")
