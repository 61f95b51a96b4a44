"""The descent EKF (:mod:`estimators.descent_nav`) behind the :class:`~renderlab.contracts.navigation.NavigationFilter`
contract, registered as filter ``descent_ekf``.

Measurement kinds: ``"pixel"`` (``z`` the stacked (s, l) of k landmarks (2k,), ``R`` (2k, 2k) px², context
``points_body_m`` (k, 3), ``R_body_from_cam`` (3, 3) from the star tracker, ``camera`` (a
:class:`renderlab.geometry.camera.CameraModel`), optional ``flagged`` (k,) bool: the method's outliers);
``"los"`` (the coastline kind: ``points_eci_m``, ``R_cam_from_eci``, read in the filter's frame); ``"position"``.
Options: None (defaults), a :class:`estimators.descent_nav.DescentNavOptions`, or a mapping of its fields.
``update`` returns the NIS over the landmarks the χ² gate kept and dof = 2 per kept landmark (``accepted`` False
when all were rejected); :attr:`last` holds the estimator's :class:`~estimators.descent_nav.DescentUpdate` (which
landmarks were kept, flagged, gated). ``set_input(u)`` passes the accelerometer's reading (body frame, m/s²).
With the option ``map_states`` on (``"estimate"`` or ``"consider"``) a ``"pixel"`` measurement also needs context
``landmark_ids`` (k,) and ``landmark_cov_m2`` (k, 3, 3) (the declared map covariance, body frame); ``x`` and ``P``
stay the navigation state [r, v] (6,) and its (6, 6) covariance, :attr:`xa` / :attr:`Pa` / :attr:`map_ids` give
the augmented state.
"""

from __future__ import annotations

from dataclasses import fields

import numpy as np

from estimators.descent_nav import DescentEKF, DescentNavOptions
from renderlab.contracts.navigation import FilterMeasurement, FilterUpdate
from renderlab.errors import UserError

__all__ = ["DescentNavFilter", "descent_options"]


def descent_options(options):
    """DescentNavOptions from None, a DescentNavOptions or a mapping of its fields (UserError on unknown keys)."""
    if options is None:
        return DescentNavOptions()
    if isinstance(options, DescentNavOptions):
        return options
    if hasattr(options, "keys"):
        known = {f.name for f in fields(DescentNavOptions)}
        unknown = sorted(set(options) - known)
        if unknown:
            raise UserError(f"descent_ekf: unknown option {unknown[0]!r} (known: {', '.join(sorted(known))})")
        return DescentNavOptions(**dict(options))
    raise UserError(f"descent_ekf options must be DescentNavOptions, a mapping or None, got {type(options).__name__}")


class DescentNavFilter:
    """The contract adapter of :class:`estimators.descent_nav.DescentEKF` (module docstring)."""

    name = "descent_ekf"

    def __init__(self, options=None):
        self._f = DescentEKF(descent_options(options))
        self.last = None

    @property
    def x(self):
        return None if self._f.x is None else self._f.x.copy()

    @property
    def P(self):
        return None if self._f.P is None else self._f.P.copy()

    @property
    def xa(self):
        """The whole state: [r, v] and the map errors of :attr:`map_ids` (3 each, body frame, m)."""
        return None if self._f.xa is None else self._f.xa.copy()

    @property
    def Pa(self):
        return None if self._f.Pa is None else self._f.Pa.copy()

    @property
    def map_ids(self) -> list[int]:
        return self._f.map_ids

    @property
    def t_s(self):
        return self._f.t

    def initialize(self, t0_s, x0, P0) -> None:
        self._f.initialize(t0_s, x0, P0)
        self.last = None

    def set_input(self, u_mps2) -> None:
        self._f.set_input(u_mps2)

    def propagate(self, t_s) -> None:
        self._f.propagate(t_s)

    def update(self, t_s, measurement: FilterMeasurement) -> FilterUpdate:
        if not isinstance(measurement, FilterMeasurement):
            raise UserError(f"descent_ekf: update needs a FilterMeasurement, got {type(measurement).__name__}")
        self.last = self._f.update(t_s, measurement.kind, measurement.z, measurement.R, measurement.context)
        if not (np.all(np.isfinite(self._f.xa)) and np.all(np.isfinite(self._f.Pa))):
            raise UserError("descent_ekf: the state or covariance became non-finite (diverged)")
        return FilterUpdate(nis=self.last.nis, dof=self.last.dof, accepted=bool(self.last.dof > 0))
