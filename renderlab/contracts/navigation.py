"""The navigation-filter contract: a recursive estimator of a state and its covariance from measurements.

A filter plug-in is a factory ``make(options) -> NavigationFilter``. The lab drives it with
``initialize(t0, x0, P0)``, then per time ``propagate(t)`` and ``update(t, measurement)`` and reads ``x``/``P``.
A *measurement* is a :class:`FilterMeasurement`: the observed vector ``z`` and its noise covariance ``R``;
how ``z`` is predicted from the state is the filter's own model (that is what a filter *is*), named by the
measurement's ``kind`` (``"los"``: line-of-sight unit vectors in the camera frame, 2 dof each; ``"position"``:
a position in the filter's frame, 3 dof).

Rules (checked by ``tests/test_conformance_filter.py``): on a case where truth follows the filter's own model
and the noises are the declared Gaussians, NEES over the runs and NIS stay in their χ² bands; ``update`` returns
the NIS and its degrees of freedom; the filter never modifies its inputs.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

from renderlab.contracts.observable import ObservableKind
from renderlab.contracts.reasons import FilterReason


@dataclass(frozen=True)
class FilterMeasurement:
    """One time's measurements: ``z`` (m,), noise covariance ``R`` (m, m), and model inputs in ``context``."""

    kind: str
    z: np.ndarray
    R: np.ndarray
    context: dict = field(default_factory=dict)


@dataclass(frozen=True)
class FilterUpdate:
    """What one update did: normalised innovation squared, its dof, and whether it was used."""

    nis: float
    dof: int
    accepted: bool = True


@runtime_checkable
class NavigationFilter(Protocol):
    """A recursive state estimator (module docstring)."""

    name: str

    @property
    def x(self) -> np.ndarray: ...

    @property
    def P(self) -> np.ndarray: ...

    def initialize(self, t0_s: float, x0: np.ndarray, P0: np.ndarray) -> None: ...

    def propagate(self, t_s: float) -> None: ...

    def update(self, t_s: float, measurement: FilterMeasurement) -> FilterUpdate: ...


#: the filter kind (:mod:`renderlab.contracts.observable`): one row per run and time; its methods are the
#: :data:`renderlab.plugins.filters`
FILTER = ObservableKind(
    name="filter", description="navigation-filter time steps: estimation errors, covariance, NEES and NIS",
    reasons=FilterReason, frame=FilterMeasurement, result=FilterUpdate, protocol=NavigationFilter,
    result_schema="renderlab.contracts.schemas:FILTER_CORE", methods="renderlab.filters",
    scorer="renderlab.campaign.scoring:score_filter",
    report_section="renderlab.report.filter_section:filter_report_section",
    conformance="renderlab.measurement.conformance_filter:check_filter_method",
)
