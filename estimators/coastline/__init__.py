"""Coastline navigation (Straub & Christian): the onboard EKF on matched coastline LOS measurements.

- :mod:`.dynamics`: two-body model (eq. 10-13) and the state transition matrix (eq. 3 in STM form).
- :mod:`.los`: the LOS measurement model (eq. 14-18) and the unit-vector noise helpers.
- :mod:`.ekf`: :class:`BatchCoastlineEKF`, N filters in lock-step (eq. 6-9, 19, Joseph eq. 7), NIS/NEES.
- :mod:`.sqrt_ekf`: the same filter in square-root (array-form QR) form, for conditioning checks.
- :mod:`.extract`: coastline edge points from a sensor image (segmentation, morphology, cloud rejection/flags).
- :mod:`.match`: registration of the onboard database projected with the a-priori state → matched LOS.
"""

from .dynamics import MU_EARTH, dynamics_jacobian, propagate_state_stm, two_body_rhs
from .ekf import BatchCoastlineEKF, EKFOptions, UpdateResult, nees
from .los import los_jacobian_position, los_predict, perturb_unit_vectors, small_rotation_matrices

__all__ = ["MU_EARTH", "dynamics_jacobian", "propagate_state_stm", "two_body_rhs", "BatchCoastlineEKF",
           "EKFOptions", "UpdateResult", "nees", "los_jacobian_position", "los_predict", "perturb_unit_vectors",
           "small_rotation_matrices"]
