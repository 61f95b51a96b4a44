r"""Onboard descent navigation: an EKF of position and velocity in the asteroid-fixed frame from landmark pixels.

Description
-----------
The filter of C. A. Wright, J. Van Eepoel, A. Liounis, M. Shoemaker, K. DeWeese, K. Getzandanner, "Relative
Terrain Imaging Navigation (RETINA) Tool for the Asteroid Redirect Robotic Mission (ARRM)", NASA GSFC, 2016
(Fig. 2 and its text:
the navigation filter fuses several Δs/Δl per image with star-tracker and gyro data into position and velocity
relative to the asteroid, and its covariance sets Retina's a-priori pose and search distance). State
x = [r (m), v (m/s)] in the asteroid-fixed (rotating) frame; dynamics eq. D1 (:mod:`.dynamics`: point-mass gravity
of the onboard GM, Coriolis and centrifugal terms, the accelerometer's non-gravitational acceleration as a known
input), STM eqs. D2–D3 by RK4; process noise D4 (unmodelled acceleration) + D5 (accelerometer noise held over its
sample). Measurements (:mod:`.measurements`): landmark pixel coordinates (s, l) of known maplet centres through the
camera model (Wright et al. eqs. 1–4) with the star-tracker attitude, eq. M1; the star tracker's error enters the
image's covariance, eq. M3. Update (:mod:`.ekf`): per-landmark χ² gate on the marginal innovation (eq. U2) plus
rejection of the method's own outliers (Retina's final output phase), joint Joseph-form update (eq. U3), NIS (U4).

Optional landmark map-error states (:mod:`.map_states`, option ``map_states``): an onboard map's landmark is off
by an error fixed for the whole descent (the maplet's mapping error), which white pixel noise cannot describe —
a filter that treats it as white averages it down and becomes over-confident. With ``"estimate"`` each landmark
in use carries its position error δp (3 states, body frame) with the declared map covariance as prior, eq. L1
(∂h/∂δp = −∂h/∂r), augmented at its first measurement (L2), marginalised after ``map_keep_updates`` images
without it (L3), constant in between (L4); ``"consider"`` is the Schmidt–Kalman variant (the map states' gain set
to zero: carried, never estimated). ``"off"`` (default) is the filter without them.

Tuning
------
``q_acc_m2_s3`` covers what the onboard model lacks — the truth's gravity differs (GM error, J2) and the
accelerometer's zero-order hold; size it so that √(q·Δt) over the image interval exceeds the largest unmodelled
acceleration × Δt (the descent study's choice is documented in its scenario). ``sigma_input_mps2`` is the
accelerometer's per-sample noise. The measurement R (eq. M3) takes the landmark method's pixel noise σ_px — the
filter is consistent only if σ_px covers the method's actual error, bias included — and the star tracker's σ.
``gate_probability`` (default 1 − 10⁻⁶, i.e. 27.6 for 2 dof) rejects gross errors and keeps a correct filter's
innovations (one false rejection per 10⁶ landmarks). With map states, the landmark error splits into the map
covariance C_i (``context["landmark_cov_m2"]``: the part fixed on the ground for the landmark's whole track) and
the white σ_px of eq. M3 (what changes from image to image): both come from the map's declared accuracy or from a
calibration of the landmark method on a campaign other than the one scored (the descent study fits them per method
and maplet tier, :mod:`renderlab.studies.descent_navigation.calibrate`). ``map_keep_updates`` must exceed the
longest gap in a landmark's track (a landmark re-augmented after marginalisation forgets its correlations).

Use
---
``f = DescentEKF(DescentNavOptions(gm_m3_s2=..., omega_rad_s=(0, 0, ω), q_acc_m2_s3=..., sigma_input_mps2=...))``;
``f.initialize(t0, x0, P0)``; per accelerometer sample ``f.set_input(u); f.propagate(t)``; per image
``f.update(t, "pixel", z, pixel_covariance(cam, points, f.x[:3], R_st, σ_px, σ_st), {"points_body_m": points,
"R_body_from_cam": R_st, "camera": cam, "flagged": outliers})``; with ``map_states="estimate"`` add
``"landmark_ids": ids, "landmark_cov_m2": C`` (k,), (k, 3, 3) to the context; ``f.x``, ``f.P`` stay [r, v] and
its covariance, ``f.xa``, ``f.Pa``, ``f.map_ids`` are the augmented state. The lab's contract adapter is
``renderlab.measurement.descent_filter.DescentNavFilter`` (registered filter ``descent_ekf``).

References
----------
C. A. Wright et al., "Relative Terrain Imaging Navigation (RETINA) Tool for the Asteroid Redirect Robotic Mission
(ARRM)", NASA Goddard Space Flight Center, 2016 (the loop and eqs. 1–4; a technical report, no DOI).

Y. Bar-Shalom, X. R. Li and T. Kirubarajan, *Estimation with Applications to Tracking and Navigation*, Wiley, 2001,
doi:10.1002/0471221279 (the EKF, the process noise of D4–D5, the χ² gate, NEES/NIS, the iterated update).

A. I. Mourikis, N. Trawny, S. I. Roumeliotis, A. E. Johnson, A. Ansar and L. Matthies, "Vision-Aided Inertial
Navigation for Spacecraft Entry, Descent, and Landing", IEEE Transactions on Robotics 25(2), 2009, pp. 264–280,
doi:10.1109/TRO.2009.2012342 (mapped landmarks in an EKF).

D. J. Scheeres, *Orbital Motion in Strongly Perturbed Environments*, Springer-Praxis, 2012 (eq. 3.1, the rotating
frame's dynamics of D1; no DOI confirmed here). S. F. Schmidt, "Application of state-space methods to navigation
problems", Advances in Control Systems 3, 1966 (the consider filter of ``map_states = "consider"``; no DOI).
"""

from estimators.descent_nav.ekf import DescentEKF, DescentNavOptions, DescentUpdate
from estimators.descent_nav.map_states import MODES as MAP_STATE_MODES
from estimators.descent_nav.measurements import pixel_covariance

__all__ = ["DescentEKF", "DescentNavOptions", "DescentUpdate", "MAP_STATE_MODES", "pixel_covariance"]
