"""The pose-estimator contract (unknown satellite): tracked image features in, relative pose and motion out.

A pose estimator is a factory ``make(options) -> PoseEstimator`` with ``estimate(tracks) -> PoseEstimate``.
``tracks`` is a :class:`FeatureTracks`: per frame the times and the pixel positions of tracked features
(NaN where a feature is not seen) and the camera model. The result gives per frame the target's position in
the camera frame and its attitude, or ``has_result = False`` with a
:class:`~renderlab.contracts.reasons.PoseReason` value.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

from renderlab.contracts.observable import ObservableKind
from renderlab.contracts.reasons import PoseReason
from renderlab.geometry.camera import CameraModel


@dataclass(frozen=True)
class FeatureTracks:
    """``t_s`` (n,), ``sl`` (n, k, 2) px (NaN where not seen), the camera model."""

    t_s: np.ndarray
    sl: np.ndarray
    camera: CameraModel


@dataclass
class PoseEstimate:
    """Per frame: target position in the camera frame (n, 3) m and attitude quaternion (n, 4, scalar-last)."""

    position_cam_m: np.ndarray
    quat_cam_from_body_xyzw: np.ndarray
    reason: str = PoseReason.OK.value
    diagnostics: str = ""
    extra: dict = field(default_factory=dict)

    @property
    def has_result(self) -> bool:
        return self.reason == PoseReason.OK.value and bool(np.all(np.isfinite(self.position_cam_m)))


@runtime_checkable
class PoseEstimator(Protocol):
    name: str

    def estimate(self, tracks: FeatureTracks) -> PoseEstimate: ...




#: the pose kind (:mod:`renderlab.contracts.observable`): one row per run (or frame) of a pose / inertia estimate;
#: no generic report section or harness yet (the unknown-satellite study reports its own)
POSE = ObservableKind(
    name="pose", description="relative pose / inertia estimates: one row per run or frame",
    reasons=PoseReason, frame=FeatureTracks, result=PoseEstimate, protocol=PoseEstimator,
    result_schema="renderlab.contracts.schemas:POSE_CORE",
)
