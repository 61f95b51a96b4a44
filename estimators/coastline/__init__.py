"""Coastline navigation (Straub & Christian): the onboard EKF on matched coastline LOS measurements.

Description
-----------
A satellite in LEO images the Earth; coastlines (land/water boundaries) extracted from each image are matched
to an onboard coastline database; each match is a line-of-sight (LOS) unit vector to a known point, and an
EKF on the two-body orbit processes them:

- :mod:`.dynamics`: two-body model (eq. 10-13) and the state transition matrix (eq. 3 in STM form).
- :mod:`.los`: the LOS measurement model (eq. 14-18) and the unit-vector noise helpers.
- :mod:`.ekf`: :class:`BatchCoastlineEKF`, N filters in lock-step (eq. 6-9, 19, Joseph eq. 7), NIS/NEES.
- :mod:`.sqrt_ekf`: the same filter in square-root (array-form QR) form, for conditioning checks.
- :mod:`.extract`: coastline edge points from a sensor image (segmentation, morphology, cloud rejection/flags).
- :mod:`.match`: registration of the onboard database projected with the a-priori state → matched LOS.

The paper assumes coastline pixels perfectly identified; :mod:`.extract` and :mod:`.match` are the lab's
onboard-style image part (used by the image-in-the-loop study).

Tuning
------
==================================  ========  =================================================================
knob                                default   turn it when
==================================  ========  =================================================================
``EKFOptions.sigma_theta_rad``      5e-4      LOS noise σθ (eq. 18): the matching accuracy, ≈ px error / f_px
``EKFOptions.sigma_attitude_rad``   0         star-tracker noise shared by an image's LOS
``EKFOptions.q_acc_m2_s3``          0         process noise for forces the two-body model lacks (J2, drag)
``EKFOptions.gain_method``          woodbury  ``direct``: the 3m × 3m solve of eq. 19, as a check
``MatchOptions.search_px``          40        coarse registration range, px: cover the image shift of the
                                              a-priori position error
``MatchOptions.gate_px``            1.5       association gate; raise for blurred or noisy edges
``MatchOptions.points_per_image``   16        LOS per image, spread over a grid so their errors are nearly
                                              independent, as eq. 18 assumes
``MatchOptions.min_inliers``        8         fewer registered inliers: no measurement from the image
``ExtractOptions.cloud_ratio``      1.8       brightness ratio cloud / land that makes a third class a cloud
``ExtractOptions.cloud_margin_px``  2         land/water edges this close to cloud get ``FLAG_NEAR_CLOUD``
``ExtractOptions.min_region_px``    6         smaller land/water components are absorbed (islets, lakes, noise)
==================================  ========  =================================================================

Use
---
::

    from estimators.coastline.extract import extract_coastline
    from estimators.coastline.match import match_coastline
    edges = extract_coastline(dn_image - bias_dn)                        # (s, l) edge points and their flags
    m = match_coastline(edges.points[edges.clean], db_eci_m, ekf.x[0, :3], T_cam_from_eci, camera)
    if m.ok:                                                             # ekf: a BatchCoastlineEKF, N = 1
        upd = ekf.update(m.los_cam[None], db_eci_m[m.db_index], T_cam_from_eci[None])

References
----------
M. N. Straub and J. A. Christian, "Autonomous Optical Navigation for Earth-Observing Satellites Using
Coastline Matching", Department of Mechanical and Aerospace Engineering, West Virginia University, Morgantown, WV;
an AIAA conference paper, c. 2015 (equation numbers above). The paper's text names neither its venue nor a DOI,
and none could be confirmed here, so none is given.
"""

from .dynamics import MU_EARTH, dynamics_jacobian, propagate_state_stm, two_body_rhs
from .ekf import BatchCoastlineEKF, EKFOptions, UpdateResult, nees
from .los import los_jacobian_position, los_predict, perturb_unit_vectors, small_rotation_matrices

__all__ = ["MU_EARTH", "dynamics_jacobian", "propagate_state_stm", "two_body_rhs", "BatchCoastlineEKF",
           "EKFOptions", "UpdateResult", "nees", "los_jacobian_position", "los_predict", "perturb_unit_vectors",
           "small_rotation_matrices"]
