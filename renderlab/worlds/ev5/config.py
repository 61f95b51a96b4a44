"""Scenario sections of the EV5 world (``world.kind = "ev5"``) and its descent (``trajectory.kind =
"ev5_descent"``). Light: pydantic only (imported when any scenario is validated).

Every resolution is a key, so tests run a tiny world in seconds while ``scenes/ev5_descent.toml``
holds the real one (≈1 m global facets, 2 cm site cells over 64 m, 1024² camera).
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, field_validator, model_validator

from renderlab.config_types import Finite, NonNegative, Positive, Seed, Strict, Vec3

Fraction = Annotated[float, Field(ge=0, lt=1, allow_inf_nan=False)]
Odd = Annotated[int, Field(ge=3, le=401)]


class LandmarkTier(Strict):
    """A family of landmarks meant for one range band (maplet spacing ≈ GSD there: gsd_ratio ≈ 1).

    Landmarks are placed (seeded) inside a disc of ``radius_m`` around the site centre, at least
    half a maplet apart; each maplet has ``size`` × ``size`` points spaced ``spacing_m``.
    """

    name: str = Field(min_length=1)
    count: Annotated[int, Field(ge=0, le=10000)]
    spacing_m: Positive
    size: Odd = 31
    radius_m: Positive

    @model_validator(mode="after")
    def _odd(self):
        if self.size % 2 == 0:
            raise ValueError(f"size must be odd, got {self.size}")
        return self


def _default_tiers() -> list[LandmarkTier]:
    return [LandmarkTier(name="regional", count=24, spacing_m=0.20, size=31, radius_m=24.0),
            LandmarkTier(name="approach", count=24, spacing_m=0.05, size=41, radius_m=8.0),
            LandmarkTier(name="site", count=24, spacing_m=0.03, size=41, radius_m=2.5)]


class EV5Site(Strict):
    """The high-resolution landing site: a square DEM patch centred on the surface at (lat, lon)."""

    lat_deg: Annotated[float, Field(ge=-80, le=80, allow_inf_nan=False)] = 20.0
    lon_deg: Finite = 30.0
    extent_m: Positive = 64.0
    cell_m: Positive = 0.02
    taper_m: Positive = 2.0  # border strip where the detail fades into the global surface
    roughness_rms_m: NonNegative = 0.05  # fractal regolith roughness (all scales up to the patch)
    roughness_hurst: Annotated[float, Field(gt=0, lt=1, allow_inf_nan=False)] = 0.75
    crater_density_per_m2: NonNegative = 0.01  # cumulative, craters wider than 1 m
    crater_min_m: Positive = 0.3
    crater_max_m: Positive = 8.0
    boulder_density_per_m2: NonNegative = 0.02  # cumulative, boulders wider than 1 m
    boulder_sfd_slope: Positive = 3.0  # N(>D) ∝ D^-slope
    boulder_min_m: Positive = 0.15
    boulder_max_m: Positive = 2.0
    target_boulder_m: Annotated[float, Field(ge=2, le=4, allow_inf_nan=False)] = 3.0
    albedo_rms: Fraction = 0.12  # relative albedo variation (correlated), besides per-boulder albedo
    albedo_corr_m: Positive = 0.3

    @model_validator(mode="after")
    def _sizes(self):
        if self.extent_m < 20 * self.cell_m:
            raise ValueError(f"extent_m ({self.extent_m}) must be at least 20 cells of cell_m ({self.cell_m})")
        if 2 * self.taper_m >= self.extent_m:
            raise ValueError(f"taper_m ({self.taper_m}) must be less than half of extent_m ({self.extent_m})")
        if self.crater_max_m < self.crater_min_m or self.boulder_max_m < self.boulder_min_m:
            raise ValueError("crater/boulder max diameter must not be below the min diameter")
        return self


class EV5World(Strict):
    """Procedural 2008 EV5 (or a user's shape model) with a high-resolution landing site."""

    kind: Literal["ev5"] = "ev5"
    seed: Seed = 0  # the same seed makes the same body, site, catalog and maplets
    # global shape: procedural (Busch et al. 2011) unless shape_file (OBJ, PLY or Gaskell ICQ) is given
    shape_file: str | None = None  # relative to the scenario file
    shape_file_units: Literal["m", "km"] = "km"
    size_m: Vec3 = [420.0, 410.0, 390.0]  # full extents of the procedural body
    ridge_height_m: NonNegative = 8.0
    concavity_diameter_m: NonNegative = 150.0
    concavity_depth_m: NonNegative = 15.0
    concavity_lat_deg: Annotated[float, Field(ge=-90, le=90, allow_inf_nan=False)] = -15.0
    concavity_lon_deg: Finite = 200.0
    roughness_rms_m: NonNegative = 3.0  # global large-scale topography
    global_craters: Annotated[int, Field(ge=0, le=5000)] = 300
    facet_m: Positive = 1.0  # edge length of the global facets (icosphere level chosen from it)
    # photometry: Hapke with C-type parameters (253 Mathilde, Clark et al. 1999); w = 0.085 gives a
    # normal albedo π r(0, 0, 0) ≈ 0.10 (C-type)
    law: Literal["lambert", "lommel_seeliger", "mcewen", "hapke"] = "hapke"
    law_params: dict[str, Finite] = {}
    albedo: Annotated[float, Field(gt=0, le=1, allow_inf_nan=False)] = 0.085
    albedo_rms: Fraction = 0.08  # relative albedo variation of the global surface
    # spin state (Busch et al. 2011): retrograde, P = 3.725 h, pole (λ, β) ≈ (180°, −84°)
    rotation_period_h: Positive = 3.725
    pole_lambda_deg: Finite = 180.0
    pole_beta_deg: Annotated[float, Field(ge=-90, le=90, allow_inf_nan=False)] = -84.0
    site: EV5Site = EV5Site()
    landmarks: list[LandmarkTier] = Field(default_factory=_default_tiers)
    mapping_error_m: NonNegative = 0.03  # rms of maplet height errors (the survey maps to 3 cm)
    mapping_error_corr_cells: NonNegative = 1.0  # Gaussian correlation length of the error, maplet cells
    albedo_error_rms: NonNegative = 0.02  # relative albedo error of the maplets

    @model_validator(mode="after")
    def _tiers(self):
        names = [t.name for t in self.landmarks]
        if len(set(names)) != len(names):
            raise ValueError(f"landmark tier names must be unique, got {names}")
        half = self.site.extent_m / 2 - self.site.taper_m
        for t in self.landmarks:
            if t.radius_m + (t.size - 1) / 2 * t.spacing_m * 1.5 > half:
                raise ValueError(f"landmark tier '{t.name}': radius_m {t.radius_m} plus the maplet half-width "
                                 f"does not fit inside the site (half-extent less taper {half:g} m)")
            if t.spacing_m < self.site.cell_m:
                raise ValueError(f"landmark tier '{t.name}': spacing_m {t.spacing_m} is finer than the site "
                                 f"cell_m {self.site.cell_m} (maplets are coarser than the truth)")
        return self


class EV5DescentTrajectory(Strict):
    """Hold point → 1 km → 200 m waypoint → 50 m (spin matched) → surface over the landing site.

    Altitudes are above the site centre along its normal. Above ``spin_match_altitude_m`` the
    spacecraft moves on a line fixed in inertial space (so it sweeps around the site in the body
    frame); below it is spin-matched and descends along the site normal. The sun is fixed in
    inertial space; ``phase_deg`` and ``sun_azimuth_deg`` (from site east toward north) set it at
    the spin-match time. Frames: ``sampling = "altitude"`` spreads ``frames`` geometrically in
    altitude (or takes ``altitudes_m``); ``"rate"`` takes ``frames`` at ``frame_rate_hz`` from
    ``start_time_s``. ``epoch_utc`` (optional, ISO UTC) is the epoch of time 0: each manifest frame then
    carries its ``epoch_utc``.
    """

    kind: Literal["ev5_descent"] = "ev5_descent"
    start_altitude_m: Positive = 1000.0
    waypoint_altitude_m: Positive = 200.0
    spin_match_altitude_m: Positive = 50.0
    final_altitude_m: Positive = 5.0
    transfer_to_waypoint_s: Positive = 900.0
    transfer_to_spin_match_s: Positive = 600.0
    descent_rate_mps: Positive = 0.1
    phase_deg: Annotated[float, Field(ge=0, lt=90, allow_inf_nan=False)] = 30.0
    sun_azimuth_deg: Finite = 60.0
    sampling: Literal["altitude", "rate"] = "altitude"
    frames: Annotated[int, Field(gt=0, le=100000)] = 12
    altitudes_m: list[Positive] | None = None
    frame_rate_hz: Positive = 3.0
    start_time_s: NonNegative = 0.0
    epoch_utc: str | None = None

    @field_validator("epoch_utc", mode="before")
    @classmethod
    def _epoch(cls, v):
        from renderlab.trajectory_io.timescales import utc_text

        return utc_text(v)

    @model_validator(mode="after")
    def _order(self):
        a = [self.start_altitude_m, self.waypoint_altitude_m, self.spin_match_altitude_m, self.final_altitude_m]
        if not all(x > y for x, y in zip(a, a[1:])):
            raise ValueError("altitudes must decrease: start > waypoint > spin_match > final "
                             f"(got {a})")
        if self.altitudes_m is not None:
            bad = [h for h in self.altitudes_m if not (self.final_altitude_m <= h <= self.start_altitude_m)]
            if bad:
                raise ValueError(f"altitudes_m {bad[0]} is outside [final_altitude_m, start_altitude_m]")
        return self
