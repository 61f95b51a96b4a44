"""Scenario section ``[unknown_satellite]``: what one run of the campaign varies (1σ of zero-mean Gaussians, drawn
per run from its seed) and how the estimator is set up; the generic ``[perturbations]`` keys the study reads besides
it: docs/unknown_satellite.md. Light: pydantic only."""

from __future__ import annotations

from typing import Annotated

from pydantic import Field

from renderlab.contracts.config_types import NonNegative, Positive, Strict

Fraction = Annotated[float, Field(ge=0, lt=0.5, allow_inf_nan=False)]


class UnknownSatelliteStudyConfig(Strict):
    """Per-run dispersions and estimator settings of the ``unknown_satellite`` study."""

    # stage-1 initial-value errors not covered by [perturbations] (the estimator's a-priori guess)
    apriori_omega_sigma_deg_s: NonNegative = Field(0.5, description="Stage-1 initial body-rate error 1σ, per body "
                                                   "axis [deg/s]")
    apriori_ratio_sigma_frac: Fraction = Field(0.1, description="Stage-1 relative error of I1/I3 and I2/I3 "
                                               "[fraction]")
    range_prior_sigma_m: Positive = Field(0.05, description="σ of the initial-range prior (and of its draw) [m]")
    # truth dispersions (each run renders its own sequence when one of these is > 0)
    tumble_rate_sigma_frac: Fraction = Field(0.0, description="Truth: ‖ω0‖ scaled by (1 + δ), direction kept; > 0 "
                                             "renders per run [fraction]")
    initial_attitude_sigma_deg: NonNegative = Field(0.0, description="Truth: q0 rotated by a random rotation vector "
                                                    "(per axis); > 0 renders per run [deg]")
    # estimator settings
    sigma_px: Positive = Field(0.3, description="Whitening σ of stage 1 / stage 2 [px]")
    epsilon_px: Positive = Field(12.0, description="ε-neighbourhood of the tracker [px]")
    min_track_frames: Annotated[int, Field(ge=2, le=10000)] = Field(5, description="Shortest track the estimator "
                                                                    "uses [frames]")
    max_nfev: Annotated[int, Field(ge=10, le=100000)] = Field(300, description="Stage-1 evaluation budget of the "
                                                              "least-squares solver")


#: conditions of a run, one boolean ``flag_<name>`` column each in the ``scores`` table (and named in its
#: ``diagnostics``); none of them means "no result" (a run that cannot be scored fails and is recorded as failed)
RUN_FLAGS = {
    "not_converged": "stage 1 stopped on its evaluation budget",
    "inertia_boundary": "the free inertia solve was unphysical; the physical re-solve was used",
    "rigidity_rejected": "the rigidity test rejected at least one track",
    "stage2_gaps": "stage 2 left at least one frame without a pose (too few / coplanar points)",
    "rank_deficient": "FIM rank deficient beyond the inertia scale (eq. 7)",
    "unmatched_point": "a database point follows no knob tip (a spurious feature)",
    "axes_relabelled": "the principal axes came out relabelled (a discrete gauge; *_aligned scores)",
}
