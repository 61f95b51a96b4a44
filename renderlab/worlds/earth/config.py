"""Scenario sections of the Earth world (``world.kind = "earth"``) and LEO orbits
(``trajectory.kind = "leo"``). Light: pydantic only (imported when any scenario is validated)."""

from __future__ import annotations

from datetime import datetime, timezone
from typing import Annotated, Literal

from pydantic import Field, field_validator, model_validator

from renderlab.config_types import NonNegative, Positive, Seed, Strict

Fraction = Annotated[float, Field(ge=0, lt=1, allow_inf_nan=False)]
Albedo = Annotated[float, Field(ge=0, le=1, allow_inf_nan=False)]


class EarthWorld(Strict):
    """WGS-84 Earth with GSHHG land/water albedo, optional clouds, real sun for the epoch.

    The ground of each frame is a local tangent tile (ENU) following the ellipsoid, textured from the
    full-resolution GSHHG polygons at ``texture_oversample`` texture cells per ground sample distance.
    ``cloud_cover`` > 0 adds a cloud layer (its own body id, casting shadows) at ``cloud_altitude_m``.
    The onboard coastline database written with the set is GSHHG simplified to ``coast_db_tolerance_m``
    and displaced by a smooth random map error of ``coast_db_error_m`` (1σ per axis, wave scales from half to
    four times ``coast_db_error_scale_m``; see :mod:`renderlab.worlds.earth.coast_db` for the measured correlation).
    """

    kind: Literal["earth"] = "earth"
    seed: Seed = 0
    land_albedo: Albedo = 0.25
    water_albedo: Albedo = 0.06
    texture_oversample: Annotated[float, Field(ge=2, le=16, allow_inf_nan=False)] = 2.0
    antialias: Annotated[int, Field(ge=1, le=8)] = 4
    tile_grid: Annotated[int, Field(ge=4, le=1024)] = 64
    tile_margin_px: NonNegative = 8.0
    cloud_cover: Fraction = 0.0
    cloud_altitude_m: Positive = 3000.0
    cloud_albedo: Albedo = 0.7
    cloud_scale_m: Positive = 20e3
    cloud_grid: Annotated[int, Field(ge=8, le=2048)] = 384
    coast_db_tolerance_m: NonNegative = 150.0
    coast_db_error_m: NonNegative = 300.0
    coast_db_error_scale_m: Positive = 100e3
    coast_db_margin_deg: NonNegative = 0.5


class LEOTrajectory(Strict):
    """A LEO orbit from classical elements, nadir-pointing camera.

    Frame k is taken at ``start_s + k·dt_s`` after ``epoch_utc`` (where the elements hold). ``fov_deg``
    (if set) replaces the camera's fx, fy, cx, cy by a centred square-pixel pinhole whose image width spans
    it. ``pointing_error_deg`` is the true attitude's random offset from nadir (1σ per axis, seeded by
    ``world.seed``); ``star_tracker_sigma_arcsec`` the noise of the attitude the star tracker reports.

    The elements are osculating elements in GCRF (the Earth world's inertial frame, see
    :mod:`renderlab.worlds.earth.orientation`). ``truth_model`` picks the truth orbit:

    ``"j2_rk4"`` (default)
        The lab's original model, of the onboard filters' own class: Kepler two-body, or with ``j2 = true``
        fixed-step RK4 two-body + J2 about the GCRF z axis (:func:`renderlab.dynamics.orbits.propagate`).
        Default because the published results and the tests that map studies onto the world were made with it.
    ``"zonal_dop853"``
        :func:`renderlab.dynamics.truth_orbit.propagate_truth`: DOP853 (rtol 1e-12) with EGM2008 zonals up to
        ``zonal_degree`` about the true Earth pole of each epoch, plus ``drag`` (exponential atmosphere, ``drag_cd``),
        ``srp`` (cannonball, ``srp_cr``, cylindrical shadow) and ``third_body`` (Sun and Moon, ERFA ephemerides);
        ``area_to_mass_m2_kg`` is the spacecraft's cross-section over mass. ``j2`` is ignored.
    """

    kind: Literal["leo"] = "leo"
    epoch_utc: str = "2024-06-21T15:00:00Z"
    altitude_km: Annotated[float, Field(ge=150, le=40000, allow_inf_nan=False)] = 1000.0
    inclination_deg: Annotated[float, Field(ge=0, le=180, allow_inf_nan=False)] = 45.0
    eccentricity: Annotated[float, Field(ge=0, lt=0.5, allow_inf_nan=False)] = 0.0
    raan_deg: Annotated[float, Field(allow_inf_nan=False)] = 0.0
    argp_deg: Annotated[float, Field(allow_inf_nan=False)] = 0.0
    true_anomaly_deg: Annotated[float, Field(allow_inf_nan=False)] = 0.0
    j2: bool = False
    truth_model: Literal["j2_rk4", "zonal_dop853"] = "j2_rk4"
    zonal_degree: Annotated[int, Field(ge=2, le=6)] = 6
    drag: bool = False
    srp: bool = False
    third_body: bool = False
    drag_cd: Annotated[float, Field(gt=0, le=10, allow_inf_nan=False)] = 2.2
    srp_cr: Annotated[float, Field(ge=0, le=3, allow_inf_nan=False)] = 1.3
    area_to_mass_m2_kg: Annotated[float, Field(gt=0, le=10, allow_inf_nan=False)] = 0.01
    frames: Annotated[int, Field(gt=0, le=100000)] = 1
    dt_s: Positive = 30.0
    start_s: NonNegative = 0.0
    fov_deg: Annotated[float, Field(gt=0, lt=120, allow_inf_nan=False)] | None = 30.0
    pointing_error_deg: NonNegative = 0.0
    star_tracker_sigma_arcsec: NonNegative = 5.0

    @field_validator("epoch_utc", mode="before")
    @classmethod
    def _toml_datetime(cls, v):
        """An unquoted TOML date-time (``--set trajectory.epoch_utc=2024-06-21T18:00:00Z``) → ISO text."""
        if isinstance(v, datetime):
            if v.tzinfo is None:
                raise ValueError(f"give the epoch in UTC with a Z suffix: {v.isoformat()}")
            return v.astimezone(timezone.utc).isoformat().replace("+00:00", "Z")
        return v

    @field_validator("epoch_utc")
    @classmethod
    def _epoch(cls, v: str) -> str:
        try:
            datetime.fromisoformat(v.replace("Z", "+00:00"))
        except ValueError:
            raise ValueError(f"not an ISO 8601 UTC time like 2024-06-21T15:00:00Z: {v!r}") from None
        return v

    @model_validator(mode="after")
    def _truth_options(self):
        """Force-model options only mean something for ``truth_model = "zonal_dop853"``: refuse them otherwise."""
        extra = {"zonal_degree", "drag", "srp", "third_body", "drag_cd", "srp_cr", "area_to_mass_m2_kg"}
        given = sorted(n for n in extra & self.model_fields_set
                       if getattr(self, n) != type(self).model_fields[n].default)
        if self.truth_model == "j2_rk4" and given:
            raise ValueError(f"{', '.join(given)} need(s) truth_model = 'zonal_dop853' (truth_model is 'j2_rk4')")
        return self
