"""Scenario sections of the EV5 world (``world.kind = "ev5"``) and its descent (``trajectory.kind =
"ev5_descent"``). Light: pydantic only (imported when any scenario is validated).

Every resolution is a key, so tests run a tiny world in seconds while ``scenes/ev5_descent.toml``
holds the real one (≈1 m global facets, 2 cm site cells over 64 m, 1024² camera).
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, field_validator, model_validator

from renderlab.contracts.config_types import Finite, NonNegative, Positive, Seed, Strict, Vec3

Fraction = Annotated[float, Field(ge=0, lt=1, allow_inf_nan=False)]
Odd = Annotated[int, Field(ge=3, le=401)]


class LandmarkTier(Strict):
    """A family of landmarks meant for one range band (maplet spacing ≈ GSD there: gsd_ratio ≈ 1).

    Landmarks are placed (seeded) inside a disc of ``radius_m`` around the site centre, at least
    half a maplet apart; each maplet has ``size`` × ``size`` points spaced ``spacing_m``.
    """

    name: str = Field(min_length=1, description="Tier name, unique (measurement tables name it)")
    count: Annotated[int, Field(ge=0, le=10000)] = Field(description="Number of landmarks of the tier")
    spacing_m: Positive = Field(description="Maplet point spacing, not finer than world.site.cell_m [m]")
    size: Odd = Field(31, description="Maplet points per side (odd)")
    radius_m: Positive = Field(description="Landmarks lie in a disc of this radius around the site centre [m]")

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

    lat_deg: Annotated[float, Field(ge=-80, le=80, allow_inf_nan=False)] = Field(20.0, description="Latitude of "
                                                                                 "the site centre [deg]")
    lon_deg: Finite = Field(30.0, description="Longitude of the site centre [deg]")
    extent_m: Positive = Field(64.0, description="Side of the square DEM patch, at least 20 cells [m]")
    cell_m: Positive = Field(0.02, description="DEM cell size of the site [m]")
    taper_m: Positive = Field(2.0, description="Border strip where the detail fades into the global surface, less "
                              "than half of extent_m [m]")
    roughness_rms_m: NonNegative = Field(0.05, description="Fractal regolith roughness (all scales up to the "
                                         "patch) [m]")
    roughness_hurst: Annotated[float, Field(gt=0, lt=1, allow_inf_nan=False)] = Field(
        0.75, description="Hurst exponent of the fractal roughness")
    crater_density_per_m2: NonNegative = Field(0.01, description="Cumulative density of craters wider than 1 m "
                                               "[1/m²]")
    crater_min_m: Positive = Field(0.3, description="Smallest crater diameter [m]")
    crater_max_m: Positive = Field(8.0, description="Largest crater diameter [m]")
    boulder_density_per_m2: NonNegative = Field(0.02, description="Cumulative density of boulders wider than 1 m "
                                                "[1/m²]")
    boulder_sfd_slope: Positive = Field(3.0, description="Boulder size-frequency slope: N(>D) ∝ D^-slope")
    boulder_min_m: Positive = Field(0.15, description="Smallest boulder diameter [m]")
    boulder_max_m: Positive = Field(2.0, description="Largest boulder diameter [m]")
    target_boulder_m: Annotated[float, Field(ge=2, le=4, allow_inf_nan=False)] = Field(
        3.0, description="Diameter of the boulder at the site (the sampling target) [m]")
    albedo_rms: Fraction = Field(0.12, description="Relative albedo variation (correlated), besides per-boulder "
                                 "albedo [fraction]")
    albedo_corr_m: Positive = Field(0.3, description="Correlation length of the albedo variation [m]")
    # levels of detail (renderlab.worlds.ev5.tiles): the renderer gets only the tiles in the frustum
    lod: bool | Literal["auto"] = Field(
        "auto", description="Render the site as tiles with levels of detail, only those in the frustum (true); the "
        "full-resolution DEM in every frame (false: exact, its acceleration structure built once); auto: whole up to "
        "static_max_facets, tiles above. Mitsuba's LLVM variants trace a tiled site whole at full resolution by a "
        "DEM ray march (exact, nothing built per frame; $RENDERLAB_MITSUBA_TILE_DESIGN=two for the tiles)")
    static_max_facets: Annotated[int, Field(ge=0, le=10**9)] = Field(
        4_000_000, description="With lod = auto: the largest site rendered whole (2 facets per DEM cell) [facets]")
    tile_cells: Annotated[int, Field(ge=2, le=4096)] = Field(128, description="Tile side in DEM cells, a power of "
                                                            "two (the coarsest level has one cell per tile) [cells]")
    lod_pixels: Annotated[float, Field(gt=0, le=64, allow_inf_nan=False)] = Field(
        1.0, description="Coarsest facet a tile may use, in pixels at the tile's nearest point [px]")
    facets_per_pixel: Annotated[float, Field(gt=0, le=1024, allow_inf_nan=False)] | None = Field(
        None, description="Facet budget of a frame: at most this many site facets per image pixel (tiles coarsened "
        "by raising lod_pixels for that frame until they fit; unset: no budget) [facets/px]")

    def tiled(self) -> bool:
        """Whether the site is rendered as tiles (``lod``; with ``"auto"``, above ``static_max_facets``)."""
        if self.lod == "auto":
            return 2 * round(self.extent_m / self.cell_m) ** 2 > self.static_max_facets
        return bool(self.lod)

    @field_validator("tile_cells")
    @classmethod
    def _pow2(cls, v):
        if v & (v - 1):
            raise ValueError(f"tile_cells must be a power of two, got {v}")
        return v

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

    kind: Literal["ev5"] = Field("ev5", description="World kind: procedural 2008 EV5 with a landing site")
    seed: Seed = Field(0, description="The same seed makes the same body, site, catalog and maplets")
    # global shape: procedural (Busch et al. 2011) unless shape_file (OBJ, PLY or Gaskell ICQ) is given
    shape_file: str | None = Field(None, description="Global shape model (OBJ, PLY or Gaskell ICQ), relative to "
                                   "the scenario file; default: procedural (Busch et al. 2011)")
    shape_file_units: Literal["m", "km"] = Field("km", description="Length unit of shape_file")
    size_m: Vec3 = Field([420.0, 410.0, 390.0], description="Full extents of the procedural body [m]")
    ridge_height_m: NonNegative = Field(8.0, description="Height of the equatorial ridge [m]")
    concavity_diameter_m: NonNegative = Field(150.0, description="Diameter of the large concavity [m]")
    concavity_depth_m: NonNegative = Field(15.0, description="Depth of the large concavity [m]")
    concavity_lat_deg: Annotated[float, Field(ge=-90, le=90, allow_inf_nan=False)] = Field(
        -15.0, description="Latitude of the concavity centre [deg]")
    concavity_lon_deg: Finite = Field(200.0, description="Longitude of the concavity centre [deg]")
    roughness_rms_m: NonNegative = Field(3.0, description="Global large-scale topography rms [m]")
    global_craters: Annotated[int, Field(ge=0, le=5000)] = Field(300, description="Number of craters on the global "
                                                                 "shape")
    facet_m: Positive = Field(1.0, description="Edge length of the global facets (icosphere level chosen from it) "
                              "[m]")
    # photometry: Hapke with C-type parameters (253 Mathilde, Clark et al. 1999); w = 0.085 gives a
    # normal albedo π r(0, 0, 0) ≈ 0.10 (C-type)
    law: Literal["lambert", "lommel_seeliger", "mcewen", "hapke"] = Field(
        "hapke", description="Photometric law; default Hapke with C-type parameters (253 Mathilde, Clark et al. "
        "1999)")
    law_params: dict[str, Finite] = Field({}, description="Parameters of the law by name (missing: the law's "
                                          "defaults)")
    albedo: Annotated[float, Field(gt=0, le=1, allow_inf_nan=False)] = Field(
        0.085, description="Albedo (Hapke w); 0.085 gives a normal albedo π r(0, 0, 0) ≈ 0.10 (C-type)")
    albedo_rms: Fraction = Field(0.08, description="Relative albedo variation of the global surface [fraction]")
    # spin state (Busch et al. 2011): retrograde, P = 3.725 h, pole (λ, β) ≈ (180°, −84°)
    rotation_period_h: Positive = Field(3.725, description="Spin period (Busch et al. 2011: retrograde, 3.725 h) "
                                        "[h]")
    pole_lambda_deg: Finite = Field(180.0, description="Spin pole ecliptic longitude λ [deg]")
    pole_beta_deg: Annotated[float, Field(ge=-90, le=90, allow_inf_nan=False)] = Field(
        -84.0, description="Spin pole ecliptic latitude β [deg]")
    site: EV5Site = Field(EV5Site(), description="The high-resolution landing site ([world.site])")
    landmarks: list[LandmarkTier] = Field(default_factory=_default_tiers, description="Landmark tiers "
                                          "([[world.landmarks]]); default: regional, approach, site")
    mapping_error_m: NonNegative = Field(0.03, description="Rms of maplet height errors (the survey maps to 3 cm) "
                                         "[m]")
    mapping_error_corr_cells: NonNegative = Field(1.0, description="Gaussian correlation length of the mapping "
                                                  "error [maplet cells]")
    albedo_error_rms: NonNegative = Field(0.02, description="Relative albedo error of the maplets [fraction]")
    build_cache: bool = Field(True, description="Keep the built global shape and site on disk in the lab cache "
                              "folder ($RENDERLAB_CACHE/ev5_world), keyed by the world's keys and the builder's "
                              "code, and reuse them in later processes")

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

    kind: Literal["ev5_descent"] = Field("ev5_descent", description="Trajectory kind: the EV5 descent")
    start_altitude_m: Positive = Field(1000.0, description="Hold-point altitude above the site [m]")
    waypoint_altitude_m: Positive = Field(200.0, description="Waypoint altitude, below start [m]")
    spin_match_altitude_m: Positive = Field(50.0, description="Altitude where the spacecraft matches the spin, "
                                            "below the waypoint [m]")
    final_altitude_m: Positive = Field(5.0, description="Last altitude, below spin match [m]")
    transfer_to_waypoint_s: Positive = Field(900.0, description="Duration start → waypoint [s]")
    transfer_to_spin_match_s: Positive = Field(600.0, description="Duration waypoint → spin match [s]")
    descent_rate_mps: Positive = Field(0.1, description="Descent rate below spin match, along the site normal "
                                       "[m/s]")
    phase_deg: Annotated[float, Field(ge=0, lt=90, allow_inf_nan=False)] = Field(
        30.0, description="Sun phase angle at the spin-match time [deg]")
    sun_azimuth_deg: Finite = Field(60.0, description="Sun azimuth from site east toward north at the spin-match "
                                    "time [deg]")
    sampling: Literal["altitude", "rate"] = Field("altitude", description="altitude: frames spread geometrically "
                                                  "in altitude (or altitudes_m); rate: frames at frame_rate_hz")
    frames: Annotated[int, Field(gt=0, le=100000)] = Field(12, description="Number of frames (ignored "
                                                           "when altitudes_m is given)")
    altitudes_m: list[Positive] | None = Field(None, description="Explicit frame altitudes within "
                                               "final_altitude_m..start_altitude_m; replaces sampling [m]")
    frame_rate_hz: Positive = Field(3.0, description="rate sampling: frames per second [Hz]")
    start_time_s: NonNegative = Field(0.0, description="rate sampling: time of the first frame [s]")
    epoch_utc: str | None = Field(None, description="ISO UTC epoch of time 0; each manifest frame then carries its "
                                  "epoch_utc")

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
