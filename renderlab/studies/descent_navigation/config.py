"""Scenario section ``[descent_navigation]`` of the closed-loop descent-navigation study (pydantic; the truth vs
filter gravity, the declared landmark and map errors, the onboard map: docs/descent_navigation.md)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, model_validator

from renderlab.contracts.config_types import Finite, NonNegative, Positive, Strict

Unit = Annotated[float, Field(gt=0, le=1, allow_inf_nan=False)]
Name = Annotated[str, Field(pattern=r"^[A-Za-z_][A-Za-z0-9_.-]*$")]


class MeasurementSourceConfig(Strict):
    """One measurement source of ``sources`` (eq. G1 of :mod:`.sources`): the true pixel of each selected landmark
    plus injected errors. All zero and ``sigma_noise_px`` None: the filter's own measurement model."""

    name: Name = Field(description="Label of the source in the tables (as a method's name), unique")
    kind: Name = Field("geometric", description="Registered measurement-source kind (renderlab.plugins."
                       "measurement_sources)")
    bias_px: tuple[Finite, Finite] = Field((0.0, 0.0), description="Common bias mu per image axis (s, l) [px]")
    sigma_bias_px: NonNegative = Field(0.0, description="Per-landmark constant bias, rms per axis over the "
                                       "landmarks (one draw per landmark and run) [px]")
    scale: Finite = Field(0.0, description="Image scale error kappa about the principal point [-]")
    sigma_noise_px: NonNegative | None = Field(None, description="White noise per axis; None: each landmark's "
                                               "declared filter sigma (model-matched) [px]")
    map_offset_h_m: NonNegative = Field(0.0, description="Landmark offset fixed on the ground, 1 sigma per "
                                        "horizontal maplet axis (the true landmark moved; the map keeps its "
                                        "centre) [m]")
    map_offset_v_m: NonNegative | None = Field(None, description="The same along the maplet normal; None: "
                                               "map_offset_h_m [m]")


class DescentNavigationConfig(Strict):
    """Options of study ``descent_navigation`` (module docstring)."""

    methods: Annotated[list[Name], Field(max_length=16)] = Field(
        ["retina", "spc", "ncc_baseline"], description="Registered landmark-method names, unique; each drives its own "
        "copy of the filter on the same images, star-tracker and accelerometer draws and initial estimate")
    sources: Annotated[list[MeasurementSourceConfig], Field(max_length=32)] = Field(
        [], description="Measurement sources besides the landmark methods (geometric: true pixel + injected error, "
        "no images); each drives its own copy of the filter with the run's draws, as a method")
    filter: Name = Field("descent_ekf", description="Registered navigation filter (renderlab.plugins.filters)")
    sigma_px: Positive = Field(0.3, description="Declared landmark pixel noise of the filter, per axis [px]")
    sigma_px_by_method: dict[str, Positive] = Field({}, description="Per-method override of sigma_px [px]")
    sigma_ground_m: NonNegative = Field(0.0, description="Declared landmark error on the ground: each landmark's "
                                        "pixel variance is sigma_px^2 + (sigma_ground_m / GSD)^2, GSD = predicted "
                                        "range / fx [m]")
    sigma_ground_m_by_method: dict[str, NonNegative] = Field({}, description="Per-method override of "
                                                             "sigma_ground_m [m]")
    map_realisation: Literal["shared", "per_run"] = Field("shared", description="The onboard maplets: the truth "
                                                          "set's catalogue in every run, or rebuilt per run with "
                                                          "its own mapping/albedo-error draw")
    map_states: Literal["off", "estimate", "consider"] = Field("off", description="Landmark map-error states in "
                                                               "the filter: none, estimated, or considered "
                                                               "(Schmidt-Kalman)")
    map_sigma_h_m: Positive = Field(0.02, description="Declared map accuracy: landmark position error 1 sigma per "
                                    "horizontal maplet axis (prior of the map states) [m]")
    map_sigma_h_m_by_method: dict[str, Positive] = Field({}, description="Per-method override of map_sigma_h_m "
                                                         "[m]")
    landmark_error_by_method: dict[str, list[tuple[Positive, Positive, Positive]]] = Field(
        {}, description="Per method, rows [spacing_m, sigma_px, map_sigma_h_m]: the declared white pixel noise and "
        "map accuracy of the landmarks of that maplet spacing (matched within 1 %), overriding sigma_px and "
        "map_sigma_h_m for them (a calibrated error model per landmark tier)")
    map_sigma_v_m: Positive | None = Field(None, description="Declared map accuracy along the maplet normal; None: "
                                           "the method's map_sigma_h_m [m]")
    map_keep_updates: Annotated[int, Field(ge=1)] = Field(3, description="Map states marginalised after this many "
                                                          "consecutive images without the landmark")
    star_tracker_sigma_arcsec: NonNegative = Field(10.0, description="Star-tracker attitude error 1 sigma per "
                                                   "camera axis, drawn per image [arcsec]")
    initial_position_sigma_m: Positive = Field(1.0, description="Initial position error 1 sigma per axis [m]")
    initial_velocity_sigma_mps: Positive = Field(0.01, description="Initial velocity error 1 sigma per axis [m/s]")
    accel_rate_hz: Positive = Field(1.0, description="Accelerometer sample rate (input held over each sample) [Hz]")
    accel_sigma_mps2: NonNegative = Field(2e-5, description="Accelerometer noise per sample, 1 sigma per axis [m/s^2]")
    gm_true_m3_s2: NonNegative = Field(2.9, description="Truth point-mass GM [m^3/s^2]")
    j2_true: Finite = Field(0.05, description="Truth J2 about the spin pole (body +z) [-]")
    r_ref_m: Positive = Field(200.0, description="Reference radius of the truth J2 [m]")
    gm_filter_m3_s2: NonNegative = Field(3.19, description="Onboard (filter) point-mass GM [m^3/s^2]")
    q_acc_m2_s3: NonNegative = Field(1e-10, description="Filter process noise PSD of unmodelled acceleration "
                                     "[m^2/s^3]")
    gate_probability: Unit = Field(1.0 - 1e-6, description="Per-landmark chi2 gate probability of the filter [-]")
    reject_flagged: bool = Field(True, description="Reject landmarks the method flagged as outliers")
    iterations: Annotated[int, Field(ge=1, le=50)] = Field(1, description="Gauss-Newton iterations of the filter "
                                                             "update (1: EKF; more: the iterated EKF)")
    joint_gate: bool = Field(False, description="Also gate the kept landmarks of an image jointly (drop the worst "
                             "until their NIS passes the chi2 gate)")
    max_landmarks: Annotated[int, Field(ge=1, le=200)] = Field(8, description="Landmarks attempted per image at "
                                                               "most (GSD ratio closest to 1 first)")
    gsd_ratio_range: tuple[Positive, Positive] = Field((0.4, 2.5), description="GSD ratio (image GSD / maplet "
                                                       "spacing) of the landmarks attempted [-]")
    n_sigma: Positive = Field(3.0, description="Search distance in sigma of the filter's projected covariance")
    min_search_px: Annotated[int, Field(ge=1)] = Field(2, description="Smallest search distance [px]")
    max_search_px: Annotated[int, Field(ge=1)] = Field(32, description="Largest search distance [px]")
    track_loss_frames: Annotated[int, Field(ge=1)] = Field(2, description="Track lost: this many consecutive images "
                                                           "without an accepted landmark")

    @model_validator(mode="after")
    def _check(self):
        names = self.methods + [s.name for s in self.sources]
        if not names:
            raise ValueError("give at least one of methods or sources")
        if len(set(names)) != len(names):
            raise ValueError(f"method and source names must be unique, got {names}")
        if self.max_search_px < self.min_search_px:
            raise ValueError("max_search_px must be >= min_search_px")
        if self.gsd_ratio_range[1] <= self.gsd_ratio_range[0]:
            raise ValueError("gsd_ratio_range must be increasing")
        return self

    def sigma_for(self, method: str) -> float:
        return float(self.sigma_px_by_method.get(method, self.sigma_px))

    def map_sigmas_for(self, method: str) -> tuple[float, float]:
        """(horizontal, normal) declared map σ of ``method``'s landmarks, m."""
        h = float(self.map_sigma_h_m_by_method.get(method, self.map_sigma_h_m))
        return h, float(self.map_sigma_v_m if self.map_sigma_v_m is not None else h)

    def landmark_sigmas(self, method: str, spacing_m) -> tuple:
        """(σ_px (k,), σ_map_h (k,), σ_map_v (k,)) of ``method``'s landmarks of maplet spacings ``spacing_m`` (k,):
        the row of ``landmark_error_by_method`` whose spacing matches within 1 %, else the method's defaults."""
        import numpy as np

        sp = np.asarray(spacing_m, float)
        px = np.full(sp.shape, self.sigma_for(method))
        h0, v0 = self.map_sigmas_for(method)
        mh, mv = np.full(sp.shape, h0), np.full(sp.shape, v0)
        for spacing, s_px, s_map in self.landmark_error_by_method.get(method, []):
            hit = np.abs(sp / spacing - 1.0) <= 0.01
            px[hit], mh[hit] = s_px, s_map
            mv[hit] = self.map_sigma_v_m if self.map_sigma_v_m is not None else s_map
        return px, mh, mv

    def ground_sigma_for(self, method: str) -> float:
        return float(self.sigma_ground_m_by_method.get(method, self.sigma_ground_m))
