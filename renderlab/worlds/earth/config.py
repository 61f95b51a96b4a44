"""Scenario sections of the Earth world (``world.kind = "earth"``) and LEO orbits
(``trajectory.kind = "leo"``). Light: pydantic only (imported when any scenario is validated)."""

from __future__ import annotations

import math
from datetime import datetime, timezone
from typing import Annotated, Literal

from pydantic import Field, field_validator, model_validator

from renderlab.contracts.config_types import NonNegative, Positive, Seed, Strict
from renderlab.errors import UserError

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

    kind: Literal["earth"] = Field("earth", description="World kind: WGS-84 Earth with GSHHG coastlines")
    seed: Seed = Field(0, description="Seed of the clouds, the coastline map error and the pointing error")
    land_albedo: Albedo = Field(0.25, description="Lambert albedo of land")
    water_albedo: Albedo = Field(0.06, description="Lambert albedo of water")
    texture_oversample: Annotated[float, Field(ge=2, le=16, allow_inf_nan=False)] = Field(
        2.0, description="Texture cells per ground sample distance of the tile's land/water raster")
    antialias: Annotated[int, Field(ge=1, le=8)] = Field(4, description="Sub-cells per texture cell and axis of the "
                                                         "land coverage (antialias² per cell)")
    tile_grid: Annotated[int, Field(ge=4, le=1024)] = Field(64, description="Ground tile mesh cells per image axis "
                                                            "(the tile follows the ellipsoid)")
    tile_margin_px: NonNegative = Field(8.0, description="Margin of the ground tile beyond the image border [px]")
    cloud_cover: Fraction = Field(0.0, description="Cloud cover; > 0 adds a cloud layer (its own body id, casting "
                                  "shadows) [fraction]")
    cloud_altitude_m: Positive = Field(3000.0, description="Altitude of the cloud layer [m]")
    cloud_albedo: Albedo = Field(0.7, description="Lambert albedo of the clouds")
    cloud_scale_m: Positive = Field(20e3, description="Smallest wave scale of the cloud field [m]")
    cloud_grid: Annotated[int, Field(ge=8, le=2048)] = Field(384, description="Cloud layer mesh cells per image "
                                                             "axis")
    coast_db_tolerance_m: NonNegative = Field(150.0, description="Onboard coastline database: GSHHG simplified to "
                                              "this tolerance [m]")
    coast_db_error_m: NonNegative = Field(300.0, description="Smooth random map error of the database, 1σ per axis "
                                          "[m]")
    coast_db_error_scale_m: Positive = Field(100e3, description="Map error wave scales from half to four times this "
                                             "(renderlab.worlds.earth.coast_db) [m]")
    coast_db_margin_deg: NonNegative = Field(0.5, description="Database region: the frames' footprints grown by "
                                             "this margin [deg]")


class LEOTrajectory(Strict):
    """A LEO orbit from classical elements, nadir-pointing camera.

    Frame k is taken at ``start_s + k·dt_s`` after ``epoch_utc`` (where the elements hold). The camera is the
    ``[camera]`` section, the one source of the field of view (:func:`leo_camera`): ``fov_deg`` here is the older
    spelling of ``camera.fov_deg`` (a centred square-pixel pinhole whose image width spans it), folded into the
    camera when the scenario is validated and refused when the camera says otherwise. ``pointing_error_deg`` is the true attitude's random offset from nadir (1σ per axis, seeded by
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
    ``"egm2008_dop853"``
        The same with the full EGM2008 field to ``gravity_degree`` and ``gravity_order`` (≤ 20) evaluated in ITRF
        through the world's GCRF → ITRF rotation (:mod:`renderlab.dynamics.geopotential`): the tesseral terms move
        a LEO orbit by kilometres per day against the zonals alone.
    """

    kind: Literal["leo"] = Field("leo", description="Trajectory kind: a LEO orbit, nadir-pointing camera")
    epoch_utc: str = Field("2024-06-21T15:00:00Z", description="ISO UTC epoch where the elements hold (Z suffix)")
    altitude_km: Annotated[float, Field(ge=150, le=40000, allow_inf_nan=False)] = Field(
        1000.0, description="Altitude above the equatorial radius (semi-major axis − R) [km]")
    inclination_deg: Annotated[float, Field(ge=0, le=180, allow_inf_nan=False)] = Field(
        45.0, description="Inclination [deg]")
    eccentricity: Annotated[float, Field(ge=0, lt=0.5, allow_inf_nan=False)] = Field(
        0.0, description="Eccentricity")
    raan_deg: Annotated[float, Field(allow_inf_nan=False)] = Field(0.0, description="Right ascension of the "
                                                                   "ascending node [deg]")
    argp_deg: Annotated[float, Field(allow_inf_nan=False)] = Field(0.0, description="Argument of perigee [deg]")
    true_anomaly_deg: Annotated[float, Field(allow_inf_nan=False)] = Field(0.0, description="True anomaly at "
                                                                           "epoch_utc [deg]")
    j2: bool = Field(False, description="truth_model j2_rk4: RK4 two-body + J2 truth; false: Kepler two-body")
    truth_model: Literal["j2_rk4", "zonal_dop853", "egm2008_dop853"] = Field(
        "j2_rk4", description="Truth propagator: j2_rk4 (the filter's class of model), zonal_dop853 (EGM2008 "
        "zonals) or egm2008_dop853 (the full EGM2008 field in ITRF; renderlab.dynamics.truth_orbit)")
    zonal_degree: Annotated[int, Field(ge=2, le=6)] = Field(6, description="zonal_dop853: highest zonal degree "
                                                            "(EGM2008 J2..J6)")
    gravity_degree: Annotated[int, Field(ge=2, le=20)] = Field(20, description="egm2008_dop853: highest degree of "
                                                               "the EGM2008 field")
    gravity_order: Annotated[int, Field(ge=0, le=20)] | None = Field(None, description="egm2008_dop853: highest "
                                                                     "order (default: gravity_degree)")
    drag: bool = Field(False, description="zonal_dop853: exponential-atmosphere drag")
    srp: bool = Field(False, description="zonal_dop853: cannonball solar radiation pressure")
    third_body: bool = Field(False, description="zonal_dop853: Sun and Moon attraction")
    drag_cd: Annotated[float, Field(gt=0, le=10, allow_inf_nan=False)] = Field(2.2, description="zonal_dop853: "
                                                                                 "drag coefficient")
    srp_cr: Annotated[float, Field(ge=0, le=3, allow_inf_nan=False)] = Field(1.3, description="zonal_dop853: SRP "
                                                                               "reflectivity coefficient")
    area_to_mass_m2_kg: Annotated[float, Field(gt=0, le=10, allow_inf_nan=False)] = Field(
        0.01, description="zonal_dop853: cross-section over mass (drag and SRP) [m²/kg]")
    frames: Annotated[int, Field(gt=0, le=100000)] = Field(1, description="Number of frames")
    dt_s: Positive = Field(30.0, description="Time between frames [s]")
    start_s: NonNegative = Field(0.0, description="Time of frame 0 after epoch_utc [s]")
    fov_deg: Annotated[float, Field(gt=0, lt=120, allow_inf_nan=False)] | None = Field(
        None, description="Older spelling of camera.fov_deg (a centred square-pixel pinhole, fx = fy = (width/2) / "
        "tan(fov_deg/2)), moved into the camera; refused when the camera gives another focal length, principal point "
        "or skew. Neither given (no camera.fx/fy/fov_deg/calibration_file): the Earth camera's default, 30 [deg]")
    pointing_error_deg: NonNegative = Field(0.0, description="True attitude's random offset from nadir, 1σ per "
                                            "axis, seeded by world.seed [deg]")
    star_tracker_sigma_arcsec: NonNegative = Field(5.0, description="Noise of the attitude the star tracker "
                                                   "reports, 1σ [arcsec]")

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
        """Force-model options only mean something for the DOP853 truth models (the degree keys each for its own):
        refuse them otherwise."""
        extra = {"zonal_degree", "gravity_degree", "gravity_order", "drag", "srp", "third_body", "drag_cd", "srp_cr",
                 "area_to_mass_m2_kg"}
        own = {"j2_rk4": set(), "zonal_dop853": extra - {"gravity_degree", "gravity_order"},
               "egm2008_dop853": extra - {"zonal_degree"}}[self.truth_model]
        given = sorted(n for n in (extra - own) & self.model_fields_set
                       if getattr(self, n) != type(self).model_fields[n].default)
        if given:
            need = {"zonal_degree": "'zonal_dop853'", "gravity_degree": "'egm2008_dop853'",
                    "gravity_order": "'egm2008_dop853'"}.get(given[0], "'zonal_dop853' or 'egm2008_dop853'")
            raise ValueError(f"{', '.join(given)} need(s) truth_model = {need} (truth_model is "
                             f"'{self.truth_model}')")
        if self.gravity_order is not None and self.gravity_order > self.gravity_degree:
            raise ValueError(f"gravity_order {self.gravity_order} exceeds gravity_degree {self.gravity_degree}")
        return self


#: field of view of the ``leo`` camera when the scenario gives no focal length (the coastline paper's 30°)
DEFAULT_FOV_DEG = 30.0
#: camera keys that set the focal length (any of them makes the camera section the source of the field of view)
_FOCAL_KEYS = ("fx", "fy", "fov_deg", "calibration_file")


def _int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool) and v > 0


def _number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def leo_camera(data: dict) -> dict:
    """Scenario data whose ``[camera]`` section is the one source of the ``leo`` camera's field of view.

    ``trajectory.fov_deg`` (the older spelling) becomes the camera it always meant — ``fx = fy = (W/2) /
    tan(fov/2)``, principal point ``((W-1)/2, (H-1)/2)``, no skew, the camera's own distortion — and leaves the
    trajectory. A camera key that disagrees with it (``fov_deg``, ``fx``, ``fy``, ``cx``, ``cy``, ``skew``,
    ``skew_yx``; relative 1e-9 on the focal length, 1e-6 px on the principal point) is refused. A scenario that
    gives no focal length at all (neither key, no ``camera.fx``/``fy``/``fov_deg``/``calibration_file``) gets
    ``camera.fov_deg =`` :data:`DEFAULT_FOV_DEG` (the camera's own ``cx``/``cy``, if given, are kept). Other trajectory kinds, and values of the wrong type (left for the
    sections' validation to name), pass unchanged.

    Parameters
    ----------
    data : dict
        Raw scenario data (after ``--set`` overrides; the loader resolves ``camera.calibration_file`` first);
        not modified.

    Returns
    -------
    dict
        ``data``, or a copy with the camera filled in and ``trajectory.fov_deg`` removed.

    Raises
    ------
    UserError
        One line naming ``trajectory.fov_deg`` and the camera key it disagrees with.
    """
    traj, cam = data.get("trajectory"), data.get("camera", {})
    if not isinstance(traj, dict) or traj.get("kind") != "leo" or not isinstance(cam, dict):
        return data
    fov = traj.get("fov_deg")
    if fov is None and any(k in cam for k in _FOCAL_KEYS):
        return data
    if fov is None:  # no focal length anywhere: the Earth camera's default field of view, in the camera
        return {**data, "camera": {**cam, "fov_deg": DEFAULT_FOV_DEG}}
    width, height = cam.get("width", 256), cam.get("height", 192)
    if not (_number(fov) and 0 < fov < 120 and _int(width) and _int(height)) or "calibration_file" in cam:
        return data  # LEOTrajectory / CameraConfig name the bad value
    f = (width / 2.0) / math.tan(math.radians(fov) / 2.0)
    want = {"fx": f, "fy": f, "cx": (width - 1) / 2.0, "cy": (height - 1) / 2.0, "skew": 0.0, "skew_yx": 0.0}
    tol = {"fx": 1e-9 * f, "fy": 1e-9 * f, "cx": 1e-6, "cy": 1e-6, "skew": 1e-9 * f, "skew_yx": 1e-9 * f}
    clash = [k for k in want if k in cam and not (_number(cam[k]) and abs(cam[k] - want[k]) <= tol[k])]
    if "fov_deg" in cam and not (_number(cam["fov_deg"]) and abs(cam["fov_deg"] - fov) <= 1e-9 * fov):
        clash.insert(0, "fov_deg")
    if clash:
        k = clash[0]
        raise UserError(f"trajectory.fov_deg = {fov:g} (fx = fy = {f:.10g} px, principal point at the image centre "
                        f"({want['cx']:g}, {want['cy']:g}), no skew) disagrees with camera.{k} = {cam[k]!r}; give "
                        "the field of view once, in the [camera] section (camera.fov_deg, or fx/fy/cx/cy)")
    out = dict(data)
    out["camera"] = {**{k: v for k, v in cam.items() if k != "fov_deg"}, **want}
    out["trajectory"] = {k: v for k, v in traj.items() if k != "fov_deg"}
    return out
