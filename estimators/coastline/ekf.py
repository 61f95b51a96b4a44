r"""The coastline-navigation EKF of Straub & Christian, vectorised across Monte Carlo runs.

Description
-----------
Every array carries a leading run axis N: states (N, 6), covariances (N, 6, 6). One filter object
runs N independent filters in lock-step (same measurement times, same matched database points, each
run with its own estimate, measurements and star-tracker attitude), so a 1000-run Monte Carlo is a
handful of batched numpy operations per image. State x = [r (m), v (m/s)] in the lab's ECI (eq. 11).

Theory (paper equation numbers):

- Propagation: state by eq. 10-12 (two-body), covariance by eq. 3 in the equivalent STM form
  :math:`P^- = \Phi P^+ \Phi^T + Q_d` (:mod:`.dynamics`).
- Update with all m LOS of one image at once (eq. 5-9, 16-18): stacked H (3m x 6), stacked rank-2m
  covariance R. :math:`S = HP^-H^T + R` is singular along the predicted LOS directions; the gain uses
  eq. 19, :math:`K = P^-H^T(S + \nu E)^{-1}` with :math:`E = \mathrm{blkdiag}(\mathbf{e}_i\mathbf{e}_i^T)`,
  which equals :math:`P^-H^TS^+` for every ν > 0 because :math:`H^TE = 0` (eq. 20). The default applies it
  with ν = σθ² through the matrix inversion lemma (a 3x3 or 6x6 solve per run, O(m)); ``gain_method="direct"``
  solves the 3m x 3m system with ν = mean diag(S). A test pins both to a ``numpy.linalg.pinv`` update.
- State update eq. 6; covariance by the Joseph form, eq. 7.
- NIS: :math:`\boldsymbol\nu^TS^+\boldsymbol\nu` with :math:`S^+ = (S+\nu E)^{-1} - E/\nu` (exact, since E
  is the orthogonal projector on S's null space), χ² with 2 degrees of freedom per LOS (2m per image).
- NEES (filter-study scoring): :math:`\tilde{\mathbf x}^TP^{-1}\tilde{\mathbf x}`, 6 degrees of freedom.

This module imports numpy only (estimators never import the lab's truth side). The square-root form is
:mod:`.sqrt_ekf`; the lab's one-run adapter behind the navigation-filter contract is
``renderlab.measurement.builtin_filters.CoastlineEKF``.

Tuning
------
:class:`EKFOptions`:

======================  ========  ==============================================================================
knob                    default   turn it when
======================  ========  ==============================================================================
``sigma_theta_rad``     5e-4      per-axis angular noise σθ of one matched LOS (R of eq. 18): the matching error
                                  in rad, ≈ px error / f_px
``sigma_attitude_rad``  0         star-tracker attitude noise shared by all LOS of an image; > 0 adds the
                                  correlated σ_att² GGᵀ term
``q_acc_m2_s3``         0         white-acceleration PSD of the process noise; > 0 when the truth has forces the
                                  two-body model lacks (J2, drag)
``mu_m3_s2``            MU_EARTH  the onboard model's gravitational parameter
``max_step_s``          10        RK4 step of the state/STM propagation; smaller for long gaps or low orbits
``gain_method``         woodbury  ``direct`` solves the 3m × 3m system of eq. 19 (the check; slower for many
                                  LOS)
======================  ========  ==============================================================================

Use
---
::

    from estimators.coastline import BatchCoastlineEKF, EKFOptions
    ekf = BatchCoastlineEKF(x0, P0, EKFOptions(sigma_theta_rad=5e-4))   # x0 (N, 6) ECI; P0 (6, 6) or (N, 6, 6)
    ekf.propagate(dt_s)                                                # eqs. 3, 10-13
    upd = ekf.update(y_cam, o_eci, T_cam_from_eci)   # LOS (N, m, 3); points (m, 3); star tracker (3, 3)
    upd.nis, upd.dof                                 # (N,) NIS, χ² with 2m dof; ekf.x, ekf.P the estimates

References
----------
M. N. Straub and J. A. Christian, "Autonomous Optical Navigation for Earth-Observing Satellites Using
Coastline Matching", West Virginia University, AIAA paper, c. 2015. Equation numbers above are
this paper's.

M. D. Shuster and S. D. Oh, "Three-axis Attitude Determination from Vector Observations", Journal of Guidance,
Control, and Dynamics, Vol. 4, No. 1, 1981, pp. 70–77 (the unit-vector noise model of eq. 18).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .dynamics import MU_EARTH, propagate_state_stm, white_acceleration_qd
from .los import los_jacobian_position, los_predict, skew_batch, stacked_measurement_covariance

__all__ = ["EKFOptions", "UpdateResult", "BatchCoastlineEKF", "nees"]


@dataclass(frozen=True)
class EKFOptions:
    """What the onboard filter assumes.

    Attributes
    ----------
    sigma_theta_rad : float
        Per-axis angular noise of one matched LOS (eq. 18).
    sigma_attitude_rad : float
        Per-axis star-tracker attitude noise; shared by all LOS of an image (0 = perfect attitude).
    q_acc_m2_s3 : float
        Spectral density of white acceleration process noise (0 = trust the two-body model).
    mu_m3_s2 : float
        Gravitational parameter of the onboard two-body model.
    max_step_s : float
        RK4 step of the state/STM propagation.
    gain_method : {"woodbury", "direct"}
        How :math:`(S+\\nu E)^{-1}` of eq. 19 is applied. ``"direct"`` forms the 3m x 3m matrix with
        ν = mean diag(S) and solves it; ``"woodbury"`` (default, O(m)) takes ν = σθ², so that
        :math:`S+\\nu E = \\sigma_\\theta^2 I + U C U^T` with :math:`U = [H_r, G]`,
        :math:`C = \\mathrm{blkdiag}(P_{rr}, \\sigma_{att}^2 I)`, and applies the matrix inversion lemma
        (a 3x3 or 6x6 solve per run). Both give the same K (eq. 20); a test pins it.
    """

    sigma_theta_rad: float = 5e-4
    sigma_attitude_rad: float = 0.0
    q_acc_m2_s3: float = 0.0
    mu_m3_s2: float = MU_EARTH
    max_step_s: float = 10.0
    gain_method: str = "woodbury"

    def __post_init__(self):
        if self.gain_method not in ("woodbury", "direct"):
            raise ValueError(f"gain_method must be 'woodbury' or 'direct', got {self.gain_method!r}")
        if not self.sigma_theta_rad > 0:
            raise ValueError("sigma_theta_rad must be > 0 (R of eq. 18)")


@dataclass
class UpdateResult:
    """Per-run diagnostics of one image update."""

    nis: np.ndarray          # (N,) normalized innovation squared, 2m degrees of freedom
    dof: int                 # 2m
    innovation: np.ndarray   # (N, 3m)


def nees(err: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Normalized estimation error squared eᵀP⁻¹e for err (N, n), P (N, n, n) → (N,)."""
    sol = np.linalg.solve(P, err[..., None])[..., 0]
    return np.einsum("ni,ni->n", err, sol)


class BatchCoastlineEKF:
    """N coastline EKFs in lock-step.

    Parameters
    ----------
    x0 : ndarray (N, 6)
        Initial estimates [r (m), v (m/s)], inertial.
    P0 : ndarray (6, 6) or (N, 6, 6)
        Initial covariance.
    options : EKFOptions
    """

    def __init__(self, x0: np.ndarray, P0: np.ndarray, options: EKFOptions = EKFOptions()):
        self.options = options
        self.x = np.array(x0, dtype=np.float64, ndmin=2)
        if self.x.shape[-1] != 6:
            raise ValueError(f"x0 must have shape (N, 6), got {self.x.shape}")
        N = self.x.shape[0]
        self.P = np.array(np.broadcast_to(np.asarray(P0, dtype=np.float64), (N, 6, 6)))

    @property
    def n_runs(self) -> int:
        return self.x.shape[0]

    def propagate(self, dt: float) -> np.ndarray:
        """Advance state and covariance by dt seconds (eq. 3, 10-13). Returns the STMs (N, 6, 6)."""
        o = self.options
        self.x, phi = propagate_state_stm(self.x, dt, o.mu_m3_s2, o.max_step_s)
        P = np.matmul(np.matmul(phi, self.P), np.swapaxes(phi, -1, -2))
        if o.q_acc_m2_s3 > 0.0:
            P = P + white_acceleration_qd(dt, o.q_acc_m2_s3)
        self.P = 0.5 * (P + np.swapaxes(P, -1, -2))
        return phi

    def update(self, y_cam: np.ndarray, o_inertial: np.ndarray, T_cam_from_inertial: np.ndarray) -> UpdateResult:
        """Process the m matched LOS of one image in every run (eqs. 6-9, 14-20).

        Parameters
        ----------
        y_cam : ndarray (N, m, 3)
            Measured unit LOS in the camera frame.
        o_inertial : ndarray (m, 3) or (N, m, 3)
            Database positions of the matched coastline points, inertial (m).
        T_cam_from_inertial : ndarray (3, 3) or (N, 3, 3)
            Attitude reported by the star tracker (the filter's T_C^I).
        """
        o = self.options
        N = self.n_runs
        y = np.asarray(y_cam, dtype=np.float64)
        m = y.shape[1]
        if m == 0:
            return UpdateResult(nis=np.zeros(N), dof=0, innovation=np.zeros((N, 0)))
        e_c, e_i, rho = los_predict(self.x[:, :3], o_inertial, T_cam_from_inertial)
        Hr = los_jacobian_position(e_i, rho, T_cam_from_inertial).reshape(N, 3 * m, 3)   # eq. 17
        P = self.P
        # H has a zero velocity block: H P = Hr P[:3, :], H P Hᵀ = Hr P_rr Hrᵀ.
        HP = np.matmul(Hr, P[:, :3, :])                                                   # (N, 3m, 6)
        innov = (y - e_c).reshape(N, 3 * m)
        X = np.concatenate([HP, innov[..., None]], axis=-1)                               # (N, 3m, 7)
        s2, sa2 = o.sigma_theta_rad**2, o.sigma_attitude_rad**2
        G = skew_batch(e_c).reshape(N, 3 * m, 3) if sa2 > 0.0 else None
        if o.gain_method == "direct":
            R = stacked_measurement_covariance(e_c, o.sigma_theta_rad, o.sigma_attitude_rad)  # eq. 18
            S = np.matmul(HP[:, :, :3], np.swapaxes(Hr, -1, -2)) + R
            E = np.zeros((N, m, 3, m, 3))
            idx = np.arange(m)
            E[:, idx, :, idx, :] = np.moveaxis(e_c[..., :, None] * e_c[..., None, :], 1, 0)
            nu = np.trace(S, axis1=-2, axis2=-1) / (2.0 * m)                              # eq. 19 weight
            sol = np.linalg.solve(S + nu[:, None, None] * E.reshape(N, 3 * m, 3 * m), X)  # (S + νE)⁻¹ [HP, ν]
        else:
            # ν = σθ²: S + νE = σθ² I + U C Uᵀ, U = [Hr, G], C = blkdiag(P_rr, σ_att² I); Woodbury (push-through)
            nu = np.full(N, s2)
            U = Hr if G is None else np.concatenate([Hr, G], axis=-1)
            C = P[:, :3, :3] if G is None else np.zeros((N, 6, 6))
            if G is not None:
                C[:, :3, :3] = P[:, :3, :3]
                C[:, 3:, 3:] = sa2 * np.eye(3)
            Ut = np.swapaxes(U, -1, -2)
            M = s2 * np.eye(U.shape[-1]) + np.matmul(np.matmul(Ut, U), C)
            Z = np.linalg.solve(M, np.matmul(Ut, X))
            sol = (X - np.matmul(U, np.matmul(C, Z))) / s2
        K = np.swapaxes(sol[..., :6], -1, -2)                                             # eq. 19, (N, 6, 3m)
        self.x = self.x + np.einsum("nij,nj->ni", K, innov)                               # eq. 6
        IKH = np.broadcast_to(np.eye(6), (N, 6, 6)).copy()
        IKH[:, :, :3] -= np.matmul(K, Hr)
        if o.gain_method == "direct":
            KRK = np.matmul(np.matmul(K, R), np.swapaxes(K, -1, -2))
        else:   # K R Kᵀ with R = σθ²(I − E) + σ_att² G Gᵀ, without forming the 3m x 3m R
            Ke = np.einsum("nimk,nmk->nim", K.reshape(N, 6, m, 3), e_c)
            KRK = s2 * (np.matmul(K, np.swapaxes(K, -1, -2)) - np.matmul(Ke, np.swapaxes(Ke, -1, -2)))
            if G is not None:
                KG = np.matmul(K, G)
                KRK = KRK + sa2 * np.matmul(KG, np.swapaxes(KG, -1, -2))
        Pn = np.matmul(np.matmul(IKH, P), np.swapaxes(IKH, -1, -2)) + KRK                 # eq. 7 (Joseph)
        self.P = 0.5 * (Pn + np.swapaxes(Pn, -1, -2))
        # NIS = νᵀ S⁺ ν with S⁺ = (S + νE)⁻¹ − E/ν; E ν is the projection of each point's innovation on e_i
        proj = np.einsum("nmi,nmi->nm", innov.reshape(N, m, 3), e_c)
        nis = np.einsum("ni,ni->n", innov, sol[..., 6]) - np.einsum("nm,nm->n", proj, proj) / nu
        return UpdateResult(nis=nis, dof=2 * m, innovation=innov)
