"""The true relative motion and attitude of the microsat world at its frame times (:class:`SeparationTruth`), made
by the CW / Euler propagation (:func:`renderlab.worlds.microsat.plan.separation_truth`) or a file trajectory
(:func:`renderlab.worlds.microsat.file_trajectory.file_truth`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class SeparationTruth:
    """True states at the frame times (LVLH / body frames, SI)."""

    times_s: np.ndarray          # (N,)
    rv_lvlh: np.ndarray          # (N, 6) target CM relative to chaser CM
    quat_lvlh_from_body: np.ndarray  # (N, 4) xyzw
    omega_body: np.ndarray       # (N, 3) rad/s, absolute
    inertia: np.ndarray          # (3,)
    n: float                     # mean motion, rad/s
    camera_offset_lvlh: np.ndarray
    R_lvlh_from_cam: np.ndarray  # (3, 3), or (N, 3, 3) for a file trajectory
    sun_lvlh: np.ndarray         # (N, 3)
    features_body: np.ndarray    # (M, 3)
    epochs_utc: list | None = None  # ISO UTC of each frame (a file trajectory with epochs)

    def R_lc(self, k: int) -> np.ndarray:
        """``R_lvlh_from_cam`` of frame k."""
        R = np.asarray(self.R_lvlh_from_cam)
        return R if R.ndim == 2 else R[k]
