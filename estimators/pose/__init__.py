"""Relative pose and inertia of an unknown tumbling satellite from monocular images (Ivanov et al. 2018).

- :mod:`.features`: noise filter + threshold → binary image → centroids; ε-neighbourhood tracking;
  the measurement database (stage 1 image processing, §4).
- :mod:`.rigidity`: robust fit + per-track χ² test: only rigid points enter the database.
- :mod:`.inertia`: inertia-ratio parametrisation in which every value is a physical body.
- :mod:`.onboard_model`: CW (eq. 1), Euler + gravity gradient (eq. 2), measurement model (eqs. 3-4).
- :mod:`.stage1`: batch least squares for initial state, rates, inertia ratios and points (eqs. 5-6).
- :mod:`.observability`: Fisher-information rank check (eq. 7).
- :mod:`.gauge`: gauge-free quantities (points and ω in LVLH, ‖ω‖, LVLH inertia shape) and their CRLB σ.
- :mod:`.stage2`: per-frame least-squares pose (eqs. 8-9) and the constant-gain Kalman filter (eq. 10).
"""

from .features import (Blobs, DetectOptions, MeasurementDatabase, Track, TrackOptions, build_database,
                       detect_blobs, detect_points, track_points)
from .gauge import GaugeFree, gauge_free
from .inertia import is_physical
from .observability import ObservabilityReport, fisher_information, observability, with_full_inertia
from .stage1 import EstimationError, Stage1Options, Stage1Problem, Stage1Result, solve_stage1
from .rigidity import RigidityOptions, RigidityReport, solve_rigid
from .stage2 import FLAG_NAMES, Stage2Options, Stage2Result, coplanarity, run_stage2, solve_pose, steady_gains

__all__ = ["Blobs", "detect_blobs", "GaugeFree", "gauge_free", "is_physical", "RigidityOptions", "RigidityReport", "solve_rigid",
           "DetectOptions", "MeasurementDatabase", "Track", "TrackOptions", "build_database", "detect_points",
           "track_points", "ObservabilityReport", "fisher_information", "observability", "with_full_inertia",
           "EstimationError", "Stage1Options", "Stage1Problem", "Stage1Result", "solve_stage1", "FLAG_NAMES",
           "Stage2Options", "Stage2Result", "coplanarity", "run_stage2", "solve_pose", "steady_gains"]
