"""The centre/limb contract: finding a resolved body's centre and limb in an image (cruise, approach, orbit OpNav).

A *centre/limb method* has a ``name`` and ``measure(frame) -> CentreLimbResult`` (:class:`CentreLimbMethod`). Per image
it receives a :class:`CentreLimbFrame`: the image, the *believed* camera model, the a-priori camera pose and Sun
direction in the body frame, and the body model (a triaxial ellipsoid: semi-axes and principal axes in the body
frame). It returns one :class:`CentreLimbResult`: the projected body centre (px) — the line-of-sight observable — and,
as far as the method measures them, the limb ellipse (centre, semi-axes, angle), the limb points it used, the
camera-to-body vector and range, their covariances, and a :class:`CentreLimbReason`.

Truth for the kind is the ``centre_truth`` table of the ``planet`` world
(:data:`renderlab.contracts.schemas.CENTRE_TRUTH`): projected body centre, centre of the true limb conic (off-axis it is not the projected centre,
:mod:`renderlab.geometry.conic`), its semi-axes and angle, range and line of sight.

Rules every method obeys (checked by :func:`renderlab.measurement.conformance_centre_limb.check_centre_limb_method`):

1. ``has_result`` exactly when ``centre_s`` and ``centre_l`` are finite; otherwise ``reason`` is a
   :class:`CentreLimbReason` other than ``ok`` (never a silent NaN); the reason is never empty or NaN.
2. The inputs are not modified.
3. Same inputs → bit-identical results, ``t_ms`` excepted (random draws only from ``frame.seed``).
4. Pixels in the lab's convention (``(0, 0)`` is the centre of the top-left pixel, sample = column); body frame metres;
   ``p_body = R_body_from_cam @ p_cam + position_m``; covariances in px² (centre) and m² (camera-frame vector).

The kind itself is :data:`CENTRE_LIMB` (:mod:`renderlab.contracts.observable`, registered in
:data:`renderlab.plugins.observables`): result table :mod:`renderlab.contracts.centre_limb_table`, runner
:mod:`renderlab.measurement.centre_limb_runner`, scorer :mod:`renderlab.stats.centre_limb`, report section
:mod:`renderlab.report.centre_limb_section`, conformance :mod:`renderlab.measurement.conformance_centre_limb`; its
methods are registered in ``renderlab.plugins.method_registry("centre_limb")`` (entry-point group
``renderlab.centre_limb_methods``: the lab's four and the Basilisk wrappers of :mod:`renderlab.basilisk.opnav_methods`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum
from typing import Protocol, runtime_checkable

import numpy as np

from renderlab.contracts.landmark import CameraPose
from renderlab.contracts.observable import ObservableKind
from renderlab.geometry.camera import CameraModel


class CentreLimbReason(str, Enum):
    """Why a centre/limb measurement has no result, in priority order."""

    OK = "ok"                            #: a measured centre
    OFF_IMAGE = "off_image"              #: the body is behind the camera or its predicted image misses the image
    TOO_SMALL = "too_small"              #: the predicted apparent radius is under the method's minimum
    UNLIT = "unlit"                      #: nothing lit to measure (no signal; no lit limb in the image)
    TOO_FEW_POINTS = "too_few_points"    #: fewer limb points than the method's minimum
    FIT_FAILED = "fit_failed"            #: the fit gave no ellipse / no body position (degenerate geometry)
    METHOD_ERROR = "method_error"        #: the method raised; the message is in ``diagnostics``


@dataclass(frozen=True)
class BodyModel:
    """The body as the onboard system knows it: a triaxial ellipsoid.

    Attributes
    ----------
    semi_axes_m : (3,) ndarray
        Semi-axes along the principal axes, m (equal for a sphere).
    R_body_from_principal : (3, 3) ndarray
        Principal axes in the body frame (columns).
    centre_m : (3,) ndarray
        Ellipsoid centre in the body frame, m (the centre the method measures).
    """

    semi_axes_m: np.ndarray
    R_body_from_principal: np.ndarray = field(default_factory=lambda: np.eye(3))
    centre_m: np.ndarray = field(default_factory=lambda: np.zeros(3))


@dataclass(frozen=True)
class CentreLimbFrame:
    """One image and what the onboard system believes about it.

    Attributes
    ----------
    image : (H, W) float64 ndarray
        The image (DN or radiance; not modified).
    valid : (H, W) bool ndarray or None
        Usable pixels (e.g. not saturated); None: all.
    camera : CameraModel
        The believed camera model.
    pose : CameraPose
        A-priori camera pose in the body frame.
    sun_body : (3,) ndarray
        Unit vector toward the Sun, body frame.
    body : BodyModel
        The body model.
    index, seed : int
        Frame index (messages) and seed for any random draw.
    """

    image: np.ndarray
    valid: np.ndarray | None
    camera: CameraModel
    pose: CameraPose
    sun_body: np.ndarray
    body: BodyModel
    index: int = 0
    seed: int = 0


def _nan2() -> np.ndarray:
    return np.full((2, 2), np.nan)


def _nan3() -> np.ndarray:
    return np.full((3, 3), np.nan)


@dataclass
class CentreLimbResult:
    """One image's centre/limb measurement (NaN where the method does not measure a quantity).

    Attributes
    ----------
    centre_s, centre_l : float
        Projected body centre, px (the line-of-sight observable).
    cov_centre_px2 : (2, 2) ndarray
        Its covariance, px².
    limb_centre_s, limb_centre_l, limb_a_px, limb_b_px, limb_angle_rad : float
        Fitted limb ellipse: centre, semi-axes (a ≥ b), major-axis angle from +s toward +l.
    r_cam_m : (3,) ndarray
        Camera-to-body-centre vector, camera frame, m; ``range_m`` its norm.
    cov_r_cam_m2 : (3, 3) ndarray
        Its covariance, m².
    limb_points : (n, 2) ndarray
        Limb points the method used, px.
    reason : str
        A :class:`CentreLimbReason` value (``"ok"`` with a result).
    diagnostics : str
        The method's own flags as text.
    t_ms : float
        Wall time, ms.
    extra : dict
        Anything else (not written to tables).
    """

    centre_s: float = math.nan
    centre_l: float = math.nan
    cov_centre_px2: np.ndarray = field(default_factory=_nan2)
    limb_centre_s: float = math.nan
    limb_centre_l: float = math.nan
    limb_a_px: float = math.nan
    limb_b_px: float = math.nan
    limb_angle_rad: float = math.nan
    r_cam_m: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    cov_r_cam_m2: np.ndarray = field(default_factory=_nan3)
    limb_points: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    reason: str = CentreLimbReason.OK.value
    diagnostics: str = ""
    t_ms: float = 0.0
    extra: dict = field(default_factory=dict)

    @property
    def has_result(self) -> bool:
        return bool(np.isfinite(self.centre_s) and np.isfinite(self.centre_l))

    @property
    def range_m(self) -> float:
        return float(np.linalg.norm(self.r_cam_m))

    def check(self, where: str = "") -> None:
        """Raise ``ValueError`` when the result breaks rule 1 of the module docstring."""
        CENTRE_LIMB.check_result(self, where)


@runtime_checkable
class CentreLimbMethod(Protocol):
    """A centre/limb method (module docstring)."""

    name: str

    def measure(self, frame: CentreLimbFrame) -> CentreLimbResult:
        """The body's centre (and limb) in ``frame.image``."""
        ...


CENTRE_LIMB = ObservableKind(
    name="centre_limb",
    description="centre and limb of a resolved body: line of sight, apparent size, range",
    reasons=CentreLimbReason, frame=CentreLimbFrame, result=CentreLimbResult, protocol=CentreLimbMethod,
    truth_table="centre_truth", conformance="renderlab.measurement.conformance_centre_limb:check_centre_limb_method",
    result_schema="renderlab.contracts.centre_limb_table:CENTRE_LIMB_CORE",
    known_schema="renderlab.contracts.centre_limb_table:CENTRE_LIMB_KNOWN",
    runner="renderlab.measurement.centre_limb_runner:runner", scorer="renderlab.stats.centre_limb:score_table",
    report_section="renderlab.report.centre_limb_section:report_section",
)

__all__ = ["BodyModel", "CameraModel", "CameraPose", "CentreLimbFrame", "CentreLimbMethod", "CentreLimbReason",
           "CentreLimbResult", "CENTRE_LIMB"]
