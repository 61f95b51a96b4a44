"""Frames, rotations and camera models: pure numpy/scipy, shared by the lab and the estimators.

- :mod:`.rotations`: scipy ``Rotation`` helpers (scalar-last quaternions), ``look_at`` for the lab camera
  frame (+z boresight, +x right, +y down), eq. 1 of the Retina paper (``to_camera_frame``).
- :mod:`.camera`: :class:`CameraModel`, gnomonic projection + distortion + the 2x2 pixel map
  (Retina eqs. 3-4), with an exact inverse and analytic Jacobians.
- :mod:`.distortion`: the Brown/OpenCV and Owen distortion models and their Newton inverse (dispatching to
  :mod:`.distortion_opencv`, OpenCV's full rational + thin-prism + tilt model, and :mod:`.fisheye`,
  Kannala–Brandt as in ``cv2.fisheye``).
- :mod:`.calibration`: OpenCV (``cv2.FileStorage`` YAML/JSON) and ROS ``camera_info`` calibration files → the
  camera dict (``read_calibration``; ``camera.calibration_file`` in a scenario).
"""

from .calibration import camera_from_opencv, opencv_intrinsics, read_calibration
from .camera import CameraModel
from .distortion import (
    DISTORTION_KEYS,
    MODELS,
    distort,
    distortion_jacobian,
    max_valid_radius,
    normalize_distortion,
    owen_coefficients_from_mm,
    undistort,
)
from .rotations import (
    angle_between,
    as_axis_angle,
    axis_angle,
    invert_transform,
    look_at,
    quat_xyzw,
    rotation_from_matrix,
    rotation_from_quat_xyzw,
    skew,
    to_camera_frame,
    transform_points,
)

__all__ = [
    "CameraModel",
    "camera_from_opencv",
    "opencv_intrinsics",
    "read_calibration",
    "DISTORTION_KEYS",
    "MODELS",
    "distort",
    "distortion_jacobian",
    "max_valid_radius",
    "normalize_distortion",
    "owen_coefficients_from_mm",
    "undistort",
    "angle_between",
    "as_axis_angle",
    "axis_angle",
    "invert_transform",
    "look_at",
    "quat_xyzw",
    "rotation_from_matrix",
    "rotation_from_quat_xyzw",
    "skew",
    "to_camera_frame",
    "transform_points",
]
