"""Scenario section ``[retina_vs_spc]`` of the landmark-method comparison (Wright et al., Fig. 12). Light: pydantic.
``methods`` are registered landmark-method names (:data:`renderlab.plugins.landmark_methods`), never a Python module;
``well_measured`` is the subset the findings are stated for, declared before looking at the errors: GSD ratio in
``[gsd_ratio_min, gsd_ratio_max]``, truth shadow fraction ≤ ``shadow_fraction_max``, landmark visible in the truth."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, model_validator

from renderlab.contracts.config_types import NonNegative, Positive, Strict


class WellMeasuredSubset(Strict):
    """The pre-declared well-measured subset (module docstring)."""

    gsd_ratio_min: Positive = Field(0.5, description="Lowest GSD ratio (image GSD / maplet spacing) of the subset")
    gsd_ratio_max: Positive = Field(2.0, description="Highest GSD ratio of the subset (>= gsd_ratio_min)")
    shadow_fraction_max: Annotated[float, Field(ge=0, le=1, allow_inf_nan=False)] = Field(
        0.05, description="Largest truth shadow fraction of a landmark in the subset [fraction]")

    @model_validator(mode="after")
    def _order(self):
        if self.gsd_ratio_max < self.gsd_ratio_min:
            raise ValueError(f"gsd_ratio_max ({self.gsd_ratio_max}) must be >= gsd_ratio_min ({self.gsd_ratio_min})")
        return self


class RetinaVsSpcConfig(Strict):
    """Options of study ``retina_vs_spc``."""

    methods: Annotated[list[Annotated[str, Field(pattern=r"^[A-Za-z_][A-Za-z0-9_.-]*$")]],
                       Field(min_length=1, max_length=16)] = Field(
        ["retina", "retina_refined", "spc", "ncc_baseline"], description="Registered landmark-method names, unique; "
        "every method sees the same image, a-priori draw and beliefs")
    well_measured: WellMeasuredSubset = Field(WellMeasuredSubset(), description="The pre-declared well-measured "
                                              "subset the findings are stated for")
    gross_error_px: NonNegative = Field(1.0, description="|err| above this (per axis) counts as a gross error [px]")
    sensor_noise: bool = Field(True, description="Re-expose every run's frames with new Poisson + read noise; "
                               "false: the noise-free expected DN, rounded (an error budget's switch)")
    crlb: Literal["continuous", "finite_difference"] = Field(
        "continuous", description="Registration CRLB in crlb_s/crlb_l: 'continuous' (the truth rendered again at "
        "sub-pixels, over the template's own pixels; column crlb_bound) or 'finite_difference' (the truth pixels "
        "over a square window, as every table published before the continuous bound; re-makes those tables)")

    @model_validator(mode="after")
    def _unique(self):
        if len(set(self.methods)) != len(self.methods):
            raise ValueError(f"methods must be unique, got {self.methods}")
        return self
