"""Scenario section ``[descent_gnc]`` of the closed-loop GN&C descent study (pydantic). The truth gravity is not the
onboard one (point mass ``gm_filter_m3_s2`` in the filter and the guidance); the declared landmark noise is σ_i² =
σ_px² + (σ_g / GSD_i)²; thrusters: :mod:`estimators.gnc.thrusters`; the robustness rules: ``docs/descent_gnc.md``.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, model_validator

from renderlab.contracts.config_types import Finite, NonNegative, Positive, RegisteredName, Strict


class DescentGncConfig(Strict):
    """Options of study ``descent_gnc`` (module docstring)."""

    methods: Annotated[list[RegisteredName], Field(min_length=1, max_length=16)] = Field(
        ["retina", "spc", "ncc_baseline"], description="Registered landmark methods; each flies its own closed loop "
        "on the run's draws (paired)")
    replay: bool = Field(True, description="Also fly the open-loop replay (guidance on the truth, every method's "
        "filter on the same images) on the same draws")
    guidance: RegisteredName = Field("zem_zev", description="Registered guidance law (renderlab.plugins.guidance)")
    control_period_s: Positive = Field(1.0, description="Guidance command hold period [s]")
    camera_period_s: Positive = Field(120.0, description="Image period, a whole multiple of the control period [s]")
    t_max_after_target_s: Positive = Field(120.0, description="Flight stops this long after the touchdown "
        "waypoint's time if there was no contact [s]")
    touchdown_speed_mps: Positive = Field(0.05, description="Target speed along the site normal at contact [m/s]")
    target_xy_m: tuple[Finite, Finite] = Field((0.0, 0.0), description="Landing target in site east, north [m]")
    gravity: Literal["point_mass_j2", "polyhedron"] = Field("point_mass_j2", description="Truth gravity field "
        "(polyhedron: of the world's closed uncut body, renderlab.worlds.ev5.gravity_mesh)")
    gravity_facet_m: Positive | None = Field(None, description="Facet size of the polyhedron gravity body, the "
        "same r(u) on a coarser icosphere; unset: the world's facet_m [m]")
    gm_true_m3_s2: Positive = Field(2.9, description="Truth GM [m^3/s^2]")
    j2_true: Finite = Field(0.05, description="Truth J2 about the spin pole [-]")
    r_ref_m: Positive = Field(200.0, description="Reference radius of the truth J2 [m]")
    gm_filter_m3_s2: Positive = Field(3.19, description="Onboard GM (filter and guidance prediction) [m^3/s^2]")
    q_acc_m2_s3: NonNegative = Field(1e-10, description="Filter process noise PSD [m^2/s^3]")
    sigma_px: Positive = Field(0.3, description="Declared landmark pixel noise per axis [px]")
    sigma_ground_m: NonNegative = Field(0.03, description="Declared landmark map error on the ground [m]")
    star_tracker_sigma_arcsec: NonNegative = Field(10.0, description="Star tracker 1 sigma per axis [arcsec]")
    accel_sigma_mps2: NonNegative = Field(2e-5, description="Accelerometer noise per control period [m/s^2]")
    initial_position_sigma_m: Positive = Field(1.0, description="Initial navigation error 1 sigma per axis [m]")
    initial_velocity_sigma_mps: Positive = Field(0.01, description="Initial navigation error 1 sigma per axis [m/s]")
    mass_kg: Positive = Field(500.0, description="Vehicle mass [kg]")
    max_accel_mps2: Positive = Field(0.05, description="Thrust limit over mass [m/s^2]")
    min_impulse_bit_ns: NonNegative = Field(0.05, description="Minimum impulse bit per thruster pair [N s]")
    scale_bias_sigma: NonNegative = Field(0.01, description="Thrust magnitude bias 1 sigma [-]")
    scale_sigma: NonNegative = Field(0.005, description="Thrust magnitude error per command 1 sigma [-]")
    misalignment_sigma_deg: NonNegative = Field(0.2, description="Fixed thrust misalignment 1 sigma per axis [deg]")
    pointing_sigma_deg: NonNegative = Field(0.1, description="Thrust pointing error per command 1 sigma [deg]")
    isp_s: Positive = Field(220.0, description="Specific impulse (propellant = impulse / (Isp g0)) [s]")
    max_landmarks: Annotated[int, Field(ge=1, le=200)] = Field(8, description="Landmarks attempted per image")
    gsd_ratio_range: tuple[Positive, Positive] = Field((0.35, 2.5), description="GSD ratio of the landmarks attempted [-]")
    n_sigma: Positive = Field(3.0, description="Search distance in sigma of the predicted pixel covariance")
    min_search_px: Annotated[int, Field(ge=1)] = Field(2, description="Smallest search distance [px]")
    max_search_px: Annotated[int, Field(ge=1)] = Field(32, description="Largest search distance before widening [px]")
    widen_factors: Annotated[list[Positive], Field(min_length=1, max_length=8)] = Field(
        [1.0, 2.0, 4.0], description="Search scale after 0, 1, 2.. consecutive missed images")
    nis_reject_probability: Annotated[float, Field(gt=0, le=1)] = Field(0.999, description="An image whose NIS "
        "exceeds this chi2 quantile is rejected (1: never)")
    track_loss_images: Annotated[int, Field(ge=1)] = Field(2, description="Consecutive missed images that are a track loss")

    @model_validator(mode="after")
    def _check(self):
        if len(set(self.methods)) != len(self.methods):
            raise ValueError(f"methods must be unique, got {self.methods}")
        ratio = self.camera_period_s / self.control_period_s
        if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
            raise ValueError("camera_period_s must be a whole multiple of control_period_s")
        if self.gsd_ratio_range[1] <= self.gsd_ratio_range[0]:
            raise ValueError("gsd_ratio_range must be increasing")
        if self.max_search_px < self.min_search_px:
            raise ValueError("max_search_px must be >= min_search_px")
        return self
