"""What the centre/limb methods share: the estimate they return, the reasons, and the a-priori geometry.

Inputs are read from a *frame* by attribute (the lab's ``renderlab.contracts.centre_limb.CentreLimbFrame`` has them;
any object with the same attributes does): ``image`` (H, W), ``valid`` (H, W) bool or None, ``camera``
(:class:`renderlab.geometry.CameraModel`), ``pose.R_body_from_cam`` and ``pose.position_m`` (``p_body = R p_cam +
position``), ``sun_body`` (unit, toward the Sun), ``body.semi_axes_m``, ``body.R_body_from_principal``,
``body.centre_m``.

A-priori geometry (:func:`predict`), in the camera frame: the centre ``r = Rᵀ(q − t)``, the shape matrix
``A = Uᵀ U`` with ``U = diag(1/a, 1/b, 1/c) R_pᵀ R`` (``U`` maps the camera frame onto the space where the body is
the unit sphere), the limb cone ``M = A r rᵀ A − (rᵀ A r − 1) A`` (eq. 1 of :mod:`renderlab.geometry.conic`) and its
conic in *ideal pixels* ``u = K x / z`` (the pinhole map without distortion, where the methods fit).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from renderlab.geometry.conic import cone_to_pixels, ellipse_params, limb_cone

OK, OFF_IMAGE, TOO_SMALL, UNLIT, TOO_FEW_POINTS, FIT_FAILED = (
    "ok", "off_image", "too_small", "unlit", "too_few_points", "fit_failed")


@dataclass
class Estimate:
    """A method's result (the fields of the lab's ``CentreLimbResult``; NaN where not measured)."""

    centre_s: float = math.nan
    centre_l: float = math.nan
    cov_centre_px2: np.ndarray = field(default_factory=lambda: np.full((2, 2), np.nan))
    limb_centre_s: float = math.nan
    limb_centre_l: float = math.nan
    limb_a_px: float = math.nan
    limb_b_px: float = math.nan
    limb_angle_rad: float = math.nan
    r_cam_m: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    cov_r_cam_m2: np.ndarray = field(default_factory=lambda: np.full((3, 3), np.nan))
    limb_points: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    reason: str = OK
    diagnostics: str = ""
    t_ms: float = 0.0
    extra: dict = field(default_factory=dict)

    def set_ellipse(self, ell) -> None:
        """Fill the ``limb_*`` fields from ``(centre, a, b, angle)``."""
        u0, a, b, angle = ell
        self.limb_centre_s, self.limb_centre_l = float(u0[0]), float(u0[1])
        self.limb_a_px, self.limb_b_px, self.limb_angle_rad = float(a), float(b), float(angle)


@dataclass(frozen=True)
class Prediction:
    """A-priori geometry of one frame (module docstring); ``ellipse`` is ``(centre, a, b, angle)`` in ideal px."""

    r_cam: np.ndarray
    U: np.ndarray
    K: np.ndarray
    sun_cam: np.ndarray
    centre_sl: np.ndarray
    conic: np.ndarray
    ellipse: tuple | None

    @property
    def radius_px(self) -> float:
        return math.sqrt(self.ellipse[1] * self.ellipse[2])

    @property
    def phase_rad(self) -> float:
        """Sun–centre–camera angle at the a-priori pose."""
        return math.acos(float(np.clip(-self.sun_cam @ self.r_cam / np.linalg.norm(self.r_cam), -1.0, 1.0)))

    def sun_perp(self) -> np.ndarray:
        """The Sun direction's component across the line of sight (camera frame; its norm is sin(phase))."""
        rh = self.r_cam / np.linalg.norm(self.r_cam)
        return self.sun_cam - (self.sun_cam @ rh) * rh


def predict(frame) -> Prediction:
    """The a-priori :class:`Prediction` of ``frame`` (module docstring)."""
    R = np.asarray(frame.pose.R_body_from_cam, float)
    body = frame.body
    r = R.T @ (np.asarray(body.centre_m, float) - np.asarray(frame.pose.position_m, float))
    U = np.diag(1.0 / np.asarray(body.semi_axes_m, float)) @ np.asarray(body.R_body_from_principal, float).T @ R
    K = ideal_K(frame.camera)
    C = cone_to_pixels(limb_cone(U.T @ U, r), K)
    ell = ellipse_params(C) if r[2] > 0 else None
    s = R.T @ np.asarray(frame.sun_body, float)
    return Prediction(r_cam=r, U=U, K=K, sun_cam=s / np.linalg.norm(s), centre_sl=frame.camera.project(r),
                      conic=C, ellipse=ell)


def ideal_K(camera) -> np.ndarray:
    """The pinhole map of ``camera`` without its distortion."""
    return np.asarray(camera.K_matrix, float)


def ideal_to_image(camera, u: np.ndarray) -> np.ndarray:
    """Ideal pixels (n, 2) → image pixels through the camera's distortion."""
    x = np.linalg.solve(ideal_K(camera), np.column_stack([u, np.ones(len(u))]).T).T
    return camera.project(x)


def image_to_ideal(camera, sl: np.ndarray) -> np.ndarray:
    """Image pixels (n, 2) → ideal pixels (undistorted through the camera model)."""
    rays = camera.unproject(np.asarray(sl, float))
    u = rays @ ideal_K(camera).T
    return u[:, :2] / u[:, 2:3]


def off_image(camera, pred: Prediction) -> bool:
    """True when the body is behind the camera, has no elliptic limb, or its limb's box misses the image."""
    if pred.ellipse is None:
        return True
    u0, a, b, ang = pred.ellipse
    hx = math.hypot(a * math.cos(ang), b * math.sin(ang))
    hy = math.hypot(a * math.sin(ang), b * math.cos(ang))
    box = np.array([[u0[0] - hx, u0[1] - hy], [u0[0] + hx, u0[1] - hy], [u0[0] - hx, u0[1] + hy],
                    [u0[0] + hx, u0[1] + hy]])
    sl = ideal_to_image(camera, box)
    if not np.all(np.isfinite(sl)):
        return False  # part of the box beyond the distortion's fold: let the method look
    return bool(sl[:, 0].max() < -0.5 or sl[:, 0].min() > camera.width - 0.5
                or sl[:, 1].max() < -0.5 or sl[:, 1].min() > camera.height - 0.5)


def centre_covariance(camera, r_cam: np.ndarray, cov_r: np.ndarray) -> np.ndarray:
    """Covariance (px²) of the projected centre from that of ``r_cam`` (first order, the camera's Jacobian)."""
    J = camera.project_jacobian(r_cam)
    return J @ cov_r @ J.T


def background(image, pred, margin: float) -> tuple[float, float]:
    """(median, robust σ) of the pixels farther than ``a + margin`` from the a-priori limb centre (0, 0 if few)."""
    u0, a, _, _ = pred.ellipse
    H, W = image.shape
    yy, xx = np.mgrid[0:H, 0:W]
    far = (xx - u0[0]) ** 2 + (yy - u0[1]) ** 2 > (a + margin) ** 2
    vals = image[far]
    vals = vals[np.isfinite(vals)]
    if len(vals) < 32:
        return 0.0, 0.0
    med = float(np.median(vals))
    return med, float(1.4826 * np.median(np.abs(vals - med)))
