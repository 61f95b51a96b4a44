"""One landmark's measurement in one image and the frame's final output phase (Wright et al. 2016, "Final Output
Phase"): the result every landmark method of :mod:`estimators.landmarks` returns.

A measurement is the predicted pixel and the measured shift, ``meas = pred + (Δs, Δl)``, with the peak score and
the :mod:`estimators.flags` bits that say why there is no result. The final output phase compares the frame's
shifts, which all come from one pose error, with their median and flags those farther than
``max(floor_px, k · 1.4826 · MAD)`` :data:`~estimators.flags.OUTLIER` for the filter (not dropped; the median, not
the paper's mean, so the outliers it looks for do not drag it). With fewer than three results nothing is flagged.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from estimators import flags as F
from estimators.landmarks.pose import CameraPoseEstimate


@dataclass
class LandmarkMeasurement:
    """One landmark's measurement in one image (px; NaN shifts when there is no result)."""

    landmark_id: int
    pred_s: float
    pred_l: float
    ds: float = float("nan")
    dl: float = float("nan")
    score: float = float("nan")
    flags: int = 0
    search_px: int = 0
    n_pixels: int = 0
    shadow_fraction: float = float("nan")
    t_ms: float = 0.0

    @property
    def meas_s(self) -> float:
        return self.pred_s + self.ds

    @property
    def meas_l(self) -> float:
        return self.pred_l + self.dl

    @property
    def has_result(self) -> bool:
        return not (self.flags & F.NO_RESULT_MASK) and np.isfinite(self.ds)


def facing_flags(mesh_or_maplet, pose: CameraPoseEstimate, sun_body: np.ndarray) -> int:
    """``FACING_AWAY`` when the maplet's up axis faces away from the sun or the camera."""
    M = getattr(mesh_or_maplet, "maplet", mesh_or_maplet)
    up = np.asarray(M.R_body_from_maplet, float)[:, 2]
    to_cam = np.asarray(pose.position_m, float) - np.asarray(M.center_m, float)
    return F.FACING_AWAY if (up @ np.asarray(sun_body, float) <= 0 or up @ to_cam <= 0) else 0


def final_output_phase(measurements: list, k: float = 5.0, floor_px: float = 1.0) -> np.ndarray:
    """Flag shifts inconsistent with the frame's median shift (in place); returns the median (Δs, Δl).

    Needs at least three results; with fewer nothing is flagged (there is no majority to compare with).
    """
    good = [m for m in measurements if m.has_result]
    if len(good) < 3:
        return np.full(2, np.nan)
    d = np.array([[m.ds, m.dl] for m in good])
    med = np.median(d, axis=0)
    dist = np.hypot(*(d - med).T)
    thr = max(floor_px, k * 1.4826 * float(np.median(dist)))
    for m, r in zip(good, dist):
        if r > thr:
            m.flags |= F.OUTLIER
    return med
