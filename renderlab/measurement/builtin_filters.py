r"""The lab's own navigation filters behind the :class:`~renderlab.contracts.navigation.NavigationFilter` contract:
the coastline EKF of Straub & Christian (:mod:`estimators.coastline.ekf`, eq. 19 gain and Joseph update) and its
square-root form (:mod:`estimators.coastline.sqrt_ekf`), for ONE run.

The estimators are run-vectorised (leading run axis N); these adapters drive them with N = 1, keep the filter
time, and translate a :class:`~renderlab.contracts.navigation.FilterMeasurement` of kind ``"los"`` into the
estimator's ``update(y_cam, o_inertial, T_cam_from_inertial)``. Registered in :data:`renderlab.plugins.filters`
as ``coastline_ekf`` and ``coastline_sqrt_ekf``; checked by ``tests/test_conformance_filter.py``.
"""

from __future__ import annotations

from dataclasses import fields, replace

import numpy as np

from estimators.coastline.ekf import BatchCoastlineEKF, EKFOptions
from estimators.coastline.los import skew_batch, stacked_measurement_covariance
from estimators.coastline.sqrt_ekf import SqrtBatchCoastlineEKF
from renderlab.contracts.navigation import FilterMeasurement, FilterUpdate

__all__ = ["CoastlineEKF", "CoastlineSqrtEKF", "los_noise_from_R"]

#: largest relative Frobenius residual of R against the eq. 18 form (R may be built at the true directions,
#: the adapter's basis at the measured ones: they differ by O(σθ))
_R_FORM_RTOL = 1e-2


def _options(options):
    """EKFOptions from None (defaults), an EKFOptions, or a mapping of its fields."""
    if options is None:
        return EKFOptions()
    if isinstance(options, EKFOptions):
        return options
    if hasattr(options, "keys"):
        known = {f.name for f in fields(EKFOptions)}
        unknown = sorted(set(options) - known)
        if unknown:
            raise ValueError(f"unknown coastline EKF option(s): {', '.join(unknown)}")
        return EKFOptions(**dict(options))
    raise TypeError(f"coastline EKF options must be EKFOptions, a mapping or None, got {type(options).__name__}")


def los_noise_from_R(R: np.ndarray, y_cam: np.ndarray) -> tuple[float, float]:
    r"""(σθ, σ_att) of a stacked LOS covariance of the filter's form (eq. 18 plus the shared star-tracker term).

    The filter models :math:`R = \sigma_\theta^2\,\mathrm{blkdiag}(I - \mathbf e_i\mathbf e_i^T)
    + \sigma_{att}^2\,GG^T`, :math:`G_i = [\mathbf e_i\times]`. The two coefficients are fitted by least squares
    (Frobenius) on those two matrices built from the unit directions ``y_cam``.

    Parameters
    ----------
    R : ndarray (3k, 3k)
        Declared covariance of the stacked LOS.
    y_cam : ndarray (k, 3)
        Directions the basis is built at (the measured LOS, normalised).

    Returns
    -------
    sigma_theta_rad, sigma_attitude_rad : float

    Raises
    ------
    ValueError
        If R is not of that form (relative residual above 1e-2) or σθ is not positive.
    """
    e = y_cam / np.linalg.norm(y_cam, axis=-1, keepdims=True)
    A = stacked_measurement_covariance(e[None], 1.0, 0.0)[0]
    G = skew_batch(e).reshape(-1, 3)
    B = G @ G.T
    gram = np.array([[np.vdot(A, A), np.vdot(A, B)], [np.vdot(B, A), np.vdot(B, B)]])
    rhs = np.array([np.vdot(A, R), np.vdot(B, R)])
    if len(e) == 1:      # one LOS: A = B, the two noises are indistinguishable; all of it is σθ
        c = np.array([rhs[0] / gram[0, 0], 0.0])
    else:
        c = np.linalg.solve(gram, rhs)
    resid = np.linalg.norm(R - c[0] * A - c[1] * B) / max(np.linalg.norm(R), 1e-300)
    if not (resid <= _R_FORM_RTOL and c[0] > 0 and c[1] > -_R_FORM_RTOL * c[0]):
        raise ValueError(f"coastline EKF: R is not σθ²·blkdiag(I − eeᵀ) + σ_att²·GGᵀ (residual {resid:.2g}, "
                         f"σθ² = {c[0]:.3g}, σ_att² = {c[1]:.3g})")
    return float(np.sqrt(c[0])), float(np.sqrt(max(c[1], 0.0)))


class _CoastlineAdapter:
    """One run of a batch coastline filter behind the NavigationFilter contract (see the subclasses)."""

    name = ""
    _form = "joseph"

    def __init__(self, options=None):
        self.options = _options(options)
        self._f = None
        self._t = None

    def _batch_class(self):
        raise NotImplementedError

    def _require_initialized(self) -> None:
        if self._f is None:
            raise RuntimeError(f"{self.name}: call initialize(t0, x0, P0) first")

    @property
    def t_s(self) -> float | None:
        """The filter time (s), None before ``initialize``."""
        return self._t

    @property
    def x(self) -> np.ndarray:
        """State estimate [r (m), v (m/s)], ECI, (6,) (a copy; NaN before ``initialize``)."""
        return np.full(6, np.nan) if self._f is None else np.array(self._f.x[0])

    @property
    def P(self) -> np.ndarray:
        """State covariance (6, 6) (a copy; NaN before ``initialize``)."""
        return np.full((6, 6), np.nan) if self._f is None else np.array(self._f.P[0])

    def initialize(self, t0_s: float, x0: np.ndarray, P0: np.ndarray) -> None:
        """Start (or restart) at time ``t0_s`` with estimate ``x0`` (6,) and covariance ``P0`` (6, 6)."""
        x0 = np.asarray(x0, dtype=np.float64)
        P0 = np.asarray(P0, dtype=np.float64)
        if x0.shape != (6,) or P0.shape != (6, 6):
            raise ValueError(f"{self.name}: x0 must be (6,) and P0 (6, 6), got {x0.shape} and {P0.shape}")
        self._f = self._batch_class()(x0[None].copy(), P0.copy(), self.options)
        self._t = float(t0_s)

    def propagate(self, t_s: float) -> None:
        """Two-body (+ process noise) propagation of state and covariance to ``t_s`` (eq. 3, 10-13)."""
        self._require_initialized()
        dt = float(t_s) - self._t
        if dt != 0.0:
            self._f.propagate(dt)
        self._t = float(t_s)

    def update(self, t_s: float, measurement: FilterMeasurement) -> FilterUpdate:
        """Process the k LOS of one image (eq. 6-9, 14-20); propagates to ``t_s`` first if needed.

        Returns NIS with ``dof = 2k``; an empty measurement propagates only and returns
        ``FilterUpdate(nan, 0, False)``. A malformed measurement raises ValueError and leaves the filter as it was.
        """
        self._require_initialized()
        if measurement.kind != "los":
            raise ValueError(f"{self.name}: measurement kind {measurement.kind!r} is not supported (only 'los')")
        z = np.asarray(measurement.z, dtype=np.float64)
        k = z.size // 3
        if z.ndim != 1 or z.size != 3 * k:
            raise ValueError(f"{self.name}: z must be stacked unit LOS (3k,), got shape {z.shape}")
        if k == 0:
            self.propagate(t_s)
            return FilterUpdate(nis=float("nan"), dof=0, accepted=False)
        y = z.reshape(1, k, 3)
        ctx = measurement.context
        try:
            pts = np.asarray(ctx["points_eci_m"], dtype=np.float64)
            T = np.asarray(ctx["R_cam_from_eci"], dtype=np.float64)
        except KeyError as exc:
            raise ValueError(f"{self.name}: 'los' measurement context lacks {exc.args[0]!r}") from None
        if pts.shape != (k, 3) or T.shape != (3, 3):
            raise ValueError(f"{self.name}: context points_eci_m must be ({k}, 3) and R_cam_from_eci (3, 3), "
                             f"got {pts.shape} and {T.shape}")
        opts = self.options
        if measurement.R is not None:
            R = np.asarray(measurement.R, dtype=np.float64)
            if R.shape != (3 * k, 3 * k):
                raise ValueError(f"{self.name}: R must be ({3 * k}, {3 * k}), got {R.shape}")
            s_th, s_att = los_noise_from_R(R, y[0])
            opts = replace(opts, sigma_theta_rad=s_th, sigma_attitude_rad=s_att)
        self.propagate(t_s)
        self._f.options = opts
        try:
            res = self._f.update(y, pts, T)
        finally:
            self._f.options = self.options
        return FilterUpdate(nis=float(res.nis[0]), dof=int(res.dof), accepted=True)


class CoastlineEKF(_CoastlineAdapter):
    r"""The coastline EKF (Straub & Christian; eq. 19 gain, Joseph eq. 7) for one run.

    Parameters
    ----------
    options : EKFOptions, mapping or None
        The estimator's own :class:`estimators.coastline.ekf.EKFOptions` (or a mapping of its fields);
        None for the defaults. ``sigma_theta_rad``/``sigma_attitude_rad`` are used only for a measurement
        whose ``R`` is None.

    Notes
    -----
    State: [r (m), v (m/s)] in ECI (the filter's frame), times in seconds. Measurement kind ``"los"`` (the
    only one), for the k matched points of one image:

    - ``z`` (3k,): measured unit LOS in the camera frame, stacked point by point;
    - ``R`` (3k, 3k): their covariance, of the filter's form
      :math:`\sigma_\theta^2\,\mathrm{blkdiag}(I-\mathbf e_i\mathbf e_i^T) + \sigma_{att}^2\,GG^T`,
      :math:`G_i=[\mathbf e_i\times]` (eq. 18 plus a star-tracker error shared by the image); the adapter reads
      σθ and σ_att off it (:func:`los_noise_from_R`) and uses them for this update. Another form raises
      ValueError. None: the options' σθ, σ_att;
    - ``context["points_eci_m"]`` (k, 3): the database positions of the matched points, ECI (m);
    - ``context["R_cam_from_eci"]`` (3, 3): the star tracker's attitude, camera-from-ECI (the filter's
      :math:`T_C^I`).

    ``update`` returns the NIS :math:`\nu^TS^+\nu` with ``dof = 2k`` (``accepted`` is always True: the
    filter does not gate); inputs are never modified; ``x``/``P`` return copies.
    """

    name = "coastline_ekf"

    def _batch_class(self):
        return BatchCoastlineEKF


class CoastlineSqrtEKF(_CoastlineAdapter):
    """The square-root (array-form QR) coastline EKF for one run; same model, measurement and context as
    :class:`CoastlineEKF` (see there); ``P`` is :math:`SS^T` of the carried factor."""

    name = "coastline_sqrt_ekf"

    def _batch_class(self):
        return SqrtBatchCoastlineEKF
