"""Geometric coastline options with a truth model of higher fidelity than the filter's (truth ≠ onboard model).

:class:`TruthModelOptions` adds the truth propagator's settings (``trajectory.truth_model`` and its force options
of the ``leo`` trajectory) to :class:`~renderlab.studies.coastline_ekf.geometric.CoastlineGeometricOptions`;
:func:`renderlab.dynamics.truth_orbit.propagate_for` reads them. The filter keeps its own two-body (+ J2) model.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

from renderlab.studies.coastline_ekf.geometric import CoastlineGeometricOptions

TRUTH_FIELDS = ("truth_model", "zonal_degree", "drag", "srp", "third_body", "drag_cd", "srp_cr",
                "area_to_mass_m2_kg")


@dataclass(frozen=True)
class TruthModelOptions(CoastlineGeometricOptions):
    """``truth_model = "zonal_dop853"``: DOP853 with EGM2008 zonals J2..J``zonal_degree`` (+ optional drag, SRP,
    Sun/Moon); ``"j2_rk4"``: the filter's class of model (the geometric study's default)."""

    truth_model: str = "j2_rk4"
    zonal_degree: int = 6
    drag: bool = False
    srp: bool = False
    third_body: bool = False
    drag_cd: float = 2.2
    srp_cr: float = 1.3
    area_to_mass_m2_kg: float = 0.01


def with_truth(options: CoastlineGeometricOptions, **truth) -> TruthModelOptions:
    """``options`` with the truth-model settings ``truth`` (names of :data:`TRUTH_FIELDS`)."""
    unknown = sorted(set(truth) - set(TRUTH_FIELDS))
    if unknown:
        raise ValueError(f"unknown truth option {unknown[0]!r}")
    base = {f.name: getattr(options, f.name) for f in fields(CoastlineGeometricOptions)}
    return TruthModelOptions(**base, **truth)
