"""Relative pose and inertia of an unknown tumbling satellite from monocular images (Ivanov et al. 2018).

Description
-----------
A chaser watches a noncooperative target of unknown shape and inertia tumbling after separation. Stage 1, on a
recorded arc, builds a database of tracked reference points (isolated bright features) and estimates, by batch
least squares, the target's initial relative state, body rate, inertia *ratios* (only ratios enter eq. 2) and the
points' body coordinates; stage 2 then estimates the relative pose frame by frame (PnP, eqs. 8-9) through a
constant-gain Kalman filter (eq. 10).

- :mod:`.features`: noise filter + threshold → binary image → centroids; ε-neighbourhood tracking;
  the measurement database (stage 1 image processing, §4).
- :mod:`.rigidity`: robust fit + per-track χ² test: only rigid points enter the database.
- :mod:`.inertia`: inertia-ratio parametrisation in which every value is a physical body.
- :mod:`.onboard_model`: CW (eq. 1), Euler + gravity gradient (eq. 2), measurement model (eqs. 3-4).
- :mod:`.stage1`: batch least squares for initial state, rates, inertia ratios and points (eqs. 5-6).
- :mod:`.observability`: Fisher-information rank check (eq. 7).
- :mod:`.gauge`: gauge-free quantities (points and ω in LVLH, ‖ω‖, LVLH inertia shape) and their CRLB σ.
- :mod:`.stage2`: per-frame least-squares pose (eqs. 8-9) and the constant-gain Kalman filter (eq. 10).

Frames: LVLH of the chaser (x radial, z orbit normal, y = z × x); attitude ``R_lvlh_from_body``; pixels in the
lab's convention ((0, 0) the centre of the top-left pixel).

Tuning
------
==============================================  ========  =========================================================
knob                                            default   turn it when
==============================================  ========  =========================================================
``DetectOptions.threshold_fraction``            0.45      binary threshold between background (median) and peak;
                                                          raise when lit surfaces merge with the feature points
``DetectOptions.min_area_px``, ``max_area_px``  3, 400    blob area gate: drops speckle and the bus or panels
``DetectOptions.max_elongation``, ``min_fill``  2.5, 0.6  shape gate: drops lit edges (thin lines) and ragged blobs
``TrackOptions.epsilon_px``                     12.0      ε-neighbourhood of the tracker: above the inter-frame
                                                          motion, below the spacing of the points
``TrackOptions.min_track_frames``               5         shorter tracks are dropped from the database
``RigidityOptions.alpha``                       1e-3      false-rejection probability of the per-track χ² rigidity
                                                          test
``Stage1Options.sigma_px``                      0.3       centroid noise (whitening of eq. 6); see :mod:`.stage1`
``Stage1Options.range_prior_sigma_m``           0.05      σ of the initial-range prior that fixes the monocular
                                                          scale
``Stage2Options.epsilon_px``                    10.0      association gate of stage 2; see :mod:`.stage2`
==============================================  ========  =========================================================

Use
---
::

    from estimators.pose import (Stage1Problem, TrackOptions, build_database, detect_points, observability,
                                 run_stage2, solve_stage1, track_points)
    detections = [detect_points(dn) for dn in images]                          # (K, 2) centroids per frame
    db = build_database(track_points(detections, TrackOptions()), TrackOptions())
    prob = Stage1Problem(camera, R_lvlh_from_cam, d_lvlh, n_rad_s, times_s, db, R_ref, range_prior_m)
    s1 = solve_stage1(prob, r0_guess, v0_guess, w0_guess, ratios_guess)       # or rigidity.solve_rigid
    rank = observability(prob, s1.theta, "ratios").rank                        # eq. 7
    s2 = run_stage2(detections, frames, times_s, camera, R_lvlh_from_cam, d_lvlh, n_rad_s, s1.points_body,
                    s1.inertia_ratios, s1.r0_lvlh, s1.v0_lvlh, s1.R0_lvlh_from_body, s1.omega0_body)

References
----------
D. Ivanov et al., "Relative Pose and Inertia Determination of Unknown Satellite Using Monocular Vision",
International Journal of Aerospace Engineering, vol. 2018, Article ID 9731512, 9 pages, 2018,
doi:10.1155/2018/9731512 (Keldysh
Institute of Applied Mathematics RAS; equation and section numbers above are this paper's).
"""

from .features import (
                       Blobs,
                       DetectOptions,
                       MeasurementDatabase,
                       Track,
                       TrackOptions,
                       build_database,
                       detect_blobs,
                       detect_points,
                       track_points,
)
from .gauge import GaugeFree, gauge_free
from .inertia import is_physical
from .observability import ObservabilityReport, fisher_information, observability, with_full_inertia
from .rigidity import RigidityOptions, RigidityReport, solve_rigid
from .stage1 import EstimationError, Stage1Options, Stage1Problem, Stage1Result, solve_stage1
from .stage2 import FLAG_NAMES, Stage2Options, Stage2Result, coplanarity, run_stage2, solve_pose, steady_gains

__all__ = ["Blobs", "detect_blobs", "GaugeFree", "gauge_free", "is_physical", "RigidityOptions", "RigidityReport", "solve_rigid",
           "DetectOptions", "MeasurementDatabase", "Track", "TrackOptions", "build_database", "detect_points",
           "track_points", "ObservabilityReport", "fisher_information", "observability", "with_full_inertia",
           "EstimationError", "Stage1Options", "Stage1Problem", "Stage1Result", "solve_stage1", "FLAG_NAMES",
           "Stage2Options", "Stage2Result", "coplanarity", "run_stage2", "solve_pose", "steady_gains"]
