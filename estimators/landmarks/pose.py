"""The a-priori camera pose and the landmark's pixel (Wright et al. 2016, eqs. 1–4) with its covariance and the
search distance: what every landmark method of :mod:`estimators.landmarks` starts from.

``p_body = R_body_from_cam @ p_cam + position_m``; a body-frame point goes to the camera frame (eq. 1), is projected
gnomonically (eq. 2–3), distorted and mapped to pixels (eq. 4) by the believed :class:`CameraModel`. The pixel
covariance is the first-order propagation of the a-priori position and attitude covariances through those
equations, J_t Σ_t J_tᵀ + J_θ Σ_θ J_θᵀ (J_t = −J_p Rᵀ, J_θ = J_p [x_c]×), and the search distance is n_σ times the
square root of its largest eigenvalue.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from renderlab.geometry.camera import CameraModel
from renderlab.geometry.rotations import skew


@dataclass(frozen=True)
class CameraPoseEstimate:
    """A camera pose in the body frame: ``p_body = R_body_from_cam @ p_cam + position_m``."""

    R_body_from_cam: np.ndarray
    position_m: np.ndarray

    def to_camera(self, p_body: np.ndarray) -> np.ndarray:
        """Eq. 1: body-frame points (..., 3) → camera frame."""
        return (np.asarray(p_body, float) - np.asarray(self.position_m, float)) @ np.asarray(self.R_body_from_cam, float)


def project_point(camera: CameraModel, pose: CameraPoseEstimate, p_body: np.ndarray) -> np.ndarray:
    """Eqs. 1–4: body-frame point(s) (..., 3) → pixel (s, l) (..., 2); NaN behind the camera."""
    return camera.project(pose.to_camera(p_body))


def pixel_covariance(camera: CameraModel, pose: CameraPoseEstimate, p_body: np.ndarray,
                     cov_pos_m2: np.ndarray, cov_rot_rad2: np.ndarray) -> np.ndarray:
    """2×2 covariance (px²) of the landmark's pixel from the a-priori pose covariance (module docstring)."""
    x_c = pose.to_camera(p_body)
    Jp = camera.project_jacobian(x_c)
    J_t = -Jp @ np.asarray(pose.R_body_from_cam, float).T
    J_th = Jp @ skew(x_c)
    return J_t @ np.asarray(cov_pos_m2, float) @ J_t.T + J_th @ np.asarray(cov_rot_rad2, float) @ J_th.T


def search_radius_px(camera: CameraModel, pose: CameraPoseEstimate, p_body: np.ndarray,
                     cov_pos_m2: np.ndarray, cov_rot_rad2: np.ndarray, n_sigma: float = 3.0,
                     min_px: int = 2, max_px: int = 64) -> int:
    """Search distance in whole pixels: ``ceil(n_sigma · sqrt(λ_max(Σ_px)))``, clamped to [min_px, max_px]."""
    cov = pixel_covariance(camera, pose, p_body, cov_pos_m2, cov_rot_rad2)
    if not np.all(np.isfinite(cov)):
        return int(max_px)
    lam = float(np.linalg.eigvalsh(cov)[-1])
    return int(min(max(math.ceil(n_sigma * math.sqrt(max(lam, 0.0))), min_px), max_px))
