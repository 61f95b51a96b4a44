"""The landmark-method contract: what a method that measures landmark shifts in an image receives and
returns (Retina, the SPC-style method, the NCC baseline, yours).

A *landmark method* is any object with a ``name`` and a ``measure_frame(frame) -> list[LandmarkResult]``
(:class:`LandmarkMethod`); the lab makes it from :class:`LandmarkMethodOptions` by calling the registered
factory (usually the class itself). Per image the runner (:mod:`renderlab.measurement.runner`) gives it one
:class:`LandmarkFrame`: the DN image, the *believed* camera model, the a-priori camera pose and Sun direction
in the body frame, the landmarks (maplets) predicted inside the image and each one's search distance. The
method returns one :class:`LandmarkResult` per landmark, in the same order, with the measured shift
(Δs, Δl) that moves the predicted landmark pixel onto the observed one: ``meas = pred + (Δs, Δl)``.

Rules every method obeys (checked by ``tests/test_conformance_landmark.py`` for every registered method):

1. ``has_result`` is true exactly when ``ds`` and ``dl`` are finite; otherwise ``reason`` is one of
   :class:`~renderlab.contracts.reasons.LandmarkReason` other than ``ok`` (never a silent NaN).
2. The inputs are not modified (image, masks, maplets, pose); the runner hands the image and mask read-only.
3. Same inputs → bit-identical results, timings (``t_ms``) excepted (a method that draws random numbers seeds
   from ``frame.seed``).
4. A landmark too small in the image to locate (a few pixels), off the image, or unlit gives no result.
5. One result per landmark, in the order of ``frame.landmarks``, with its ``landmark_id``.
6. Units: pixels in the lab's convention (sample = column, line = row, (0, 0) is the *centre* of the top-left
   pixel); body frame metres; ``p_body = R_body_from_cam @ p_cam + position_m``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Protocol, Sequence, runtime_checkable

import numpy as np

from renderlab.contracts.observable import ObservableKind
from renderlab.contracts.reasons import LandmarkReason
from renderlab.geometry.camera import CameraModel
from renderlab.geometry.maplet import Maplet


@dataclass(frozen=True)
class CameraPose:
    """A camera pose in the body frame: ``p_body = R_body_from_cam @ p_cam + position_m``."""

    R_body_from_cam: np.ndarray
    position_m: np.ndarray

    def to_camera(self, p_body: np.ndarray) -> np.ndarray:
        """Body-frame points (..., 3) → camera frame (Retina eq. 1)."""
        return (np.asarray(p_body, float) - np.asarray(self.position_m, float)) @ np.asarray(self.R_body_from_cam,
                                                                                              float)


@dataclass(frozen=True)
class LandmarkMethodOptions:
    """Knobs the lab passes to every landmark method (a method ignores those it has no use for).

    Attributes
    ----------
    peak : str or None
        Sub-pixel peak finder name (:data:`estimators.landmarks.peaks.FINDERS`); None: the method's own default.
    min_correlation : float
        Correlation under which a peak gives no result.
    supersample : int
        Rays (or samples) per pixel side when a method renders a template.
    psf_sigma_px : float
        Gaussian PSF σ of the predicted image, px.
    L_table : tuple of float
        Onboard McEwen L(α) tabulated over [0, π] (empty: β = exp(−α/60°), Retina eq. 5); every method of a
        comparison gets the same ground knowledge.
    """

    peak: str | None = None
    min_correlation: float = 0.3
    supersample: int = 3
    psf_sigma_px: float = 0.0
    L_table: tuple = ()


@dataclass(frozen=True)
class LandmarkFrame:
    """One image and what the onboard system believes about it.

    Attributes
    ----------
    image : (H, W) float64 ndarray
        DN of the image (not modified by methods).
    valid : (H, W) bool ndarray or None
        Usable pixels (e.g. not saturated); None: all.
    camera : CameraModel
        The believed camera model (projection eqs. 1–4 of the Retina paper).
    pose : CameraPose
        A-priori camera pose in the body frame.
    sun_body : (3,) ndarray
        Unit vector toward the Sun in the body frame.
    landmarks : sequence of Maplet
        The landmarks to measure (predicted inside the image).
    search_px : (n,) int ndarray
        Search distance per landmark, px (n σ of the projected a-priori covariance).
    index : int
        Frame index (for messages).
    seed : int
        Seed for any random draw a method makes.
    """

    image: np.ndarray
    valid: np.ndarray | None
    camera: CameraModel
    pose: CameraPose
    sun_body: np.ndarray
    landmarks: Sequence[Maplet]
    search_px: np.ndarray
    index: int = 0
    seed: int = 0


@dataclass
class LandmarkResult:
    """One landmark's measurement in one image (px; NaN shift when there is no result).

    ``reason`` is a :class:`LandmarkReason` value (``"ok"`` with a result); ``outlier`` marks a result that a
    method's own consistency check (Retina's final output phase) flags but keeps; ``diagnostics`` is free text
    of the method's own flags.
    """

    landmark_id: int
    pred_s: float
    pred_l: float
    ds: float = math.nan
    dl: float = math.nan
    score: float = math.nan
    reason: str = LandmarkReason.OK.value
    outlier: bool = False
    search_px: int = 0
    n_pixels: int = 0
    shadow_fraction: float = math.nan
    diagnostics: str = ""
    t_ms: float = 0.0
    extra: dict = field(default_factory=dict)

    @property
    def has_result(self) -> bool:
        return bool(np.isfinite(self.ds) and np.isfinite(self.dl))

    @property
    def meas_s(self) -> float:
        return self.pred_s + self.ds

    @property
    def meas_l(self) -> float:
        return self.pred_l + self.dl

    def check(self, where: str = "") -> None:
        """Raise ``ValueError`` when the result breaks rule 1 of the module docstring."""
        allowed = {r.value for r in LandmarkReason}
        if self.reason not in allowed:
            raise ValueError(f"{where}landmark {self.landmark_id}: reason {self.reason!r} is not a LandmarkReason "
                             f"({', '.join(sorted(allowed))})")
        if self.has_result != (self.reason == LandmarkReason.OK.value):
            raise ValueError(f"{where}landmark {self.landmark_id}: has_result={self.has_result} (ds={self.ds}, "
                             f"dl={self.dl}) but reason={self.reason!r}: a NaN shift needs a reason, a shift needs 'ok'")


@runtime_checkable
class LandmarkMethod(Protocol):
    """A landmark-shift method (module docstring)."""

    name: str

    def measure_frame(self, frame: LandmarkFrame) -> list[LandmarkResult]:
        """One :class:`LandmarkResult` per ``frame.landmarks`` entry, in order."""
        ...


#: the landmark kind (:mod:`renderlab.contracts.observable`): registered as ``landmark`` in
#: :data:`renderlab.plugins.observables`
LANDMARK = ObservableKind(
    name="landmark", description="landmark shifts in an image: one row per landmark attempted per image",
    reasons=LandmarkReason, frame=LandmarkFrame, result=LandmarkResult, protocol=LandmarkMethod,
    truth_table="landmark_truth", result_schema="renderlab.contracts.schemas:LANDMARK_CORE",
    known_schema="renderlab.contracts.schemas:LANDMARK_RUNNER", table_names=("measurements",),
    methods="renderlab.landmark_methods", scorer="renderlab.campaign.scoring:score_measurements",
    report_section="renderlab.report.landmark_section:landmark_report_section",
    conformance="renderlab.measurement.conformance:check_landmark_method",
)
