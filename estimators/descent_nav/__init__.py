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

Tuning
------
``q_acc_m2_s3`` covers what the onboard model lacks — the truth's gravity differs (GM error, J2) and the
accelerometer's zero-order hold; size it so that √(q·Δt) over the image interval exceeds the largest unmodelled
acceleration × Δt (the descent study's choice is documented in its scenario). ``sigma_input_mps2`` is the
accelerometer's per-sample noise. The measurement R (eq. M3) takes the landmark method's pixel noise σ_px — the
filter is consistent only if σ_px covers the method's actual error, bias included — and the star tracker's σ.
``gate_probability`` (default 1 − 10⁻⁶, i.e. 27.6 for 2 dof) rejects gross errors and keeps a correct filter's
innovations (one false rejection per 10⁶ landmarks).

Use
---
``f = DescentEKF(DescentNavOptions(gm_m3_s2=..., omega_rad_s=(0, 0, ω), q_acc_m2_s3=..., sigma_input_mps2=...))``;
``f.initialize(t0, x0, P0)``; per accelerometer sample ``f.set_input(u); f.propagate(t)``; per image
``f.update(t, "pixel", z, pixel_covariance(cam, points, f.x[:3], R_st, σ_px, σ_st), {"points_body_m": points,
"R_body_from_cam": R_st, "camera": cam, "flagged": outliers})``. The lab's contract adapter is
``renderlab.measurement.descent_filter.DescentNavFilter`` (registered filter ``descent_ekf``).
"""

from estimators.descent_nav.ekf import DescentEKF, DescentNavOptions, DescentUpdate
from estimators.descent_nav.measurements import pixel_covariance

__all__ = ["DescentEKF", "DescentNavOptions", "DescentUpdate", "pixel_covariance"]
