"""Scenario section ``[camera]``: the camera model (intrinsics in pixels, distortion). Light: pydantic only.

Besides explicit intrinsics (``fx, fy, cx, cy, skew, skew_yx, model, distortion``) the section takes

- ``calibration_file``: an OpenCV (``cv2.FileStorage`` YAML/JSON) or ROS ``camera_info`` calibration,
  relative to the scenario file (:func:`renderlab.geometry.calibration.read_calibration`). It sets every
  intrinsic, so it refuses any of them beside it; ``width``/``height`` may be given and must then match
  the file's image size (or supply it when the file has none). ``calibration_model`` declares the file's
  distortion model (``plumb_bob``, ``equidistant``, ... :data:`renderlab.geometry.calibration.MODEL_NAMES`):
  required when the file holds 4 coefficients and no fisheye flag or ``distortion_model`` of its own
  (``cv2.projectPoints``' ``k1 k2 p1 p2`` and ``cv2.fisheye``'s ``k1..k4`` look alike), checked against them
  otherwise;
- ``fov_deg``: the horizontal field of view over the full image width, ``fx = fy = (width/2) /
  tan(fov_deg/2)``, principal point at the image centre ``((width-1)/2, (height-1)/2)`` unless
  ``cx``/``cy`` are given; it refuses ``fx``/``fy`` beside it.

The camera section is the one source of the field of view: the Earth orbit's older ``trajectory.fov_deg`` is
moved into it (and refused when it disagrees, :func:`renderlab.worlds.earth.config.leo_camera`).

:func:`resolve_camera` turns both into plain intrinsics once, when the scenario is loaded (the file path
needs the scenario's folder), so the validated scenario and the manifest hold plain ``fx, fy, cx, cy,
model, distortion``; it also ties the sensor's optics to the camera's focal length (:func:`resolve_optics`).
:class:`CameraConfig` converts ``fov_deg`` itself too (for scenario data validated without the loader) and
refuses an unresolved ``calibration_file``.
"""

from __future__ import annotations

import copy
import math
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import Field, model_validator

from renderlab.contracts.config_types import Finite, Positive
from renderlab.contracts.config_types import Strict as _Strict
from renderlab.errors import UserError

__all__ = ["CameraConfig", "resolve_camera", "resolve_optics"]

#: intrinsics a calibration file sets (refused beside ``calibration_file``)
_CALIBRATED = ("fx", "fy", "cx", "cy", "skew", "skew_yx", "model", "distortion", "fov_deg")


def _fov_intrinsics(cam: dict[str, Any]) -> dict[str, Any]:
    """``cam`` with ``fov_deg`` replaced by ``fx = fy`` and a centred principal point (unless given)."""
    if "fov_deg" not in cam:
        return cam
    out = dict(cam)
    fov = out.pop("fov_deg")
    for key in ("fx", "fy"):
        if key in out:
            raise UserError(f"camera.fov_deg and camera.{key} are both given; give one (fov_deg sets fx = fy)")
    if isinstance(fov, bool) or not isinstance(fov, (int, float)) or not 0.0 < float(fov) < 180.0:
        raise UserError(f"camera.fov_deg must be a number in (0, 180) degrees, got {fov!r}")
    width = out.get("width", CameraConfig.model_fields["width"].default)
    height = out.get("height", CameraConfig.model_fields["height"].default)
    if not all(isinstance(n, int) and not isinstance(n, bool) and n > 0 for n in (width, height)):
        return out  # the section's own validation names the bad size
    f = (width / 2.0) / math.tan(math.radians(float(fov)) / 2.0)
    out.update(fx=f, fy=f)
    out.setdefault("cx", (width - 1) / 2.0)
    out.setdefault("cy", (height - 1) / 2.0)
    return out


class CameraConfig(_Strict):
    """Intrinsics in pixels (pixel centres are integers, (0, 0) is the top-left pixel's centre)."""

    width: Annotated[int, Field(gt=0, le=16384)] = Field(256, description="Image width [px]")
    height: Annotated[int, Field(gt=0, le=16384)] = Field(192, description="Image height [px]")
    fx: Positive = Field(300.0, description="Focal length along image x (columns); or give fov_deg, or "
                         "calibration_file [px]")
    fy: Positive = Field(300.0, description="Focal length along image y (rows) [px]")
    cx: Finite = Field(127.5, description="Principal point x; pixel centres are integers, (0, 0) is the top-left "
                       "pixel's centre [px]")
    cy: Finite = Field(95.5, description="Principal point y [px]")
    skew: Finite = Field(0.0, description="Off-diagonal K[0, 1] of the pixel map (sample per unit y_d), OpenCV's "
                         "skew [px]")
    skew_yx: Finite = Field(0.0, description="Off-diagonal K[1, 0] (line per unit x_d), the Retina/Owen Kyx term; "
                            "0 for OpenCV [px]")
    model: Literal["pinhole", "brown", "owen", "opencv", "kannala_brandt"] = Field(
        "pinhole", description="Distortion model (renderlab.geometry.camera.CameraModel)")
    distortion: dict[str, Finite] = Field({}, description="Coefficients by name, missing ones 0 (brown: k1 k2 k3 "
                                          "p1 p2; owen: e1..e6 in units of the focal length; opencv: k1 k2 p1 p2 "
                                          "k3 k4 k5 k6 s1 s2 s3 s4 tau_x tau_y; kannala_brandt: k1 k2 k3 k4)")

    @model_validator(mode="before")
    @classmethod
    def _plain_intrinsics(cls, data: Any) -> Any:
        if not isinstance(data, dict):
            return data
        if "calibration_model" in data and "calibration_file" not in data:
            raise ValueError("calibration_model declares the model of calibration_file, which is not given")
        if "calibration_file" in data:
            raise ValueError("calibration_file is read when the scenario file is loaded (load_scenario, which knows "
                             "its folder); pass the data through renderlab.scenario.camera.resolve_camera first")
        try:
            return _fov_intrinsics(data)
        except UserError as err:
            raise ValueError(str(err).removeprefix("camera.")) from None


def _from_calibration(cam: dict[str, Any], base_dir: Path) -> dict[str, Any]:
    from renderlab.geometry.calibration import read_calibration

    rel = cam["calibration_file"]
    if not isinstance(rel, str) or not rel.strip():
        raise UserError(f"camera.calibration_file must be a file name, got {rel!r}")
    declared = cam.get("calibration_model")
    if declared is not None and (not isinstance(declared, str) or not declared.strip()):
        raise UserError(f"camera.calibration_model must be a model name, got {declared!r}")
    clash = [k for k in _CALIBRATED if k in cam]
    if clash:
        raise UserError(f"camera.calibration_file and camera.{clash[0]} are both given; the calibration file "
                        f"sets the intrinsics (remove camera.{clash[0]})")
    try:
        cal = read_calibration(Path(base_dir) / rel, model=declared)
    except UserError as err:
        raise UserError(f"camera.calibration_file: {err}") from None
    out = {k: v for k, v in cam.items() if k not in ("calibration_file", "calibration_model")}
    for key in ("width", "height"):
        if key in cal and key in out and out[key] != cal[key]:
            raise UserError(f"camera.{key} = {out[key]!r} but the calibration file {rel} is for "
                            f"image_{key} = {cal[key]} (calibrations do not rescale; drop camera.{key})")
        if key not in cal and key not in out:
            raise UserError(f"camera.calibration_file {rel} has no image_{key}; give camera.{key}")
    return {**out, **cal}


def resolve_camera(scenario: dict[str, Any], base_dir: str | Path) -> dict[str, Any]:
    """Scenario data with ``camera.calibration_file`` and ``camera.fov_deg`` resolved to plain intrinsics.

    Parameters
    ----------
    scenario : dict
        Raw scenario data (parsed TOML with overrides applied); not modified.
    base_dir : str or Path
        The scenario file's folder; ``calibration_file`` is relative to it.

    Returns
    -------
    dict
        A copy whose ``camera`` section has explicit ``fx, fy, cx, cy`` (and, from a file, ``width, height,
        skew, skew_yx, model, distortion``), and whose ``sensor`` optics are tied to that camera's focal
        length (:func:`resolve_optics`).

    Raises
    ------
    UserError
        One line: both a calibration file and intrinsics (or ``fov_deg`` and ``fx``/``fy``), an unreadable or
        invalid calibration file, an image size that disagrees with the file's, inconsistent sensor optics.
    """
    out = copy.deepcopy(scenario)
    cam = out.get("camera", {})
    if not isinstance(cam, dict):
        return out  # validation names it
    if "calibration_file" in cam:
        cam = _from_calibration(cam, Path(base_dir))
    elif "calibration_model" in cam:
        raise UserError("camera.calibration_model declares the model of camera.calibration_file, which is not given")
    if cam or "camera" in out:
        out["camera"] = cam
    from renderlab.worlds.earth.config import leo_camera

    out = leo_camera(out)  # the Earth orbit's older trajectory.fov_deg → the camera, checked
    cam = _fov_intrinsics(out.get("camera", {}))
    if cam or "camera" in out:
        out["camera"] = cam
    sensor = out.get("sensor")
    if isinstance(sensor, dict):
        defaults = {k: CameraConfig.model_fields[k].default for k in ("fx", "fy", "skew", "skew_yx")}
        values = {k: cam.get(k, v) for k, v in defaults.items()}
        if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values.values()):
            out["sensor"] = resolve_optics(sensor, **values)
    return out


def _positive(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value) and value > 0


def resolve_optics(sensor: dict[str, Any], fx: float, fy: float, skew: float = 0.0,
                   skew_yx: float = 0.0) -> dict[str, Any]:
    """A ``sensor`` section whose optics use the camera's focal length (the one source of truth).

    The camera gives the pixel solid angle ``Ω = 1/|fx fy - skew skew_yx|`` and, with ``sensor.pixel_pitch_m``
    ``p``, the lens focal length ``f = p / sqrt(Ω)``. A ``sensor.focal_length_m`` is dropped when it agrees
    with ``f`` (0.1 %) and refused when it does not; a ``sensor.aperture_diameter_m`` ``D`` becomes
    ``sensor.f_number = f / D`` (checked against a given ``f_number``). Without those keys the section is
    returned as it is (the default f/4 needs no focal length).

    Parameters
    ----------
    sensor : dict
        Raw ``sensor`` section; not modified.
    fx, fy, skew, skew_yx : float
        The camera's pixel map (px per unit normalized coordinate).

    Returns
    -------
    dict
        The section without ``focal_length_m`` and ``aperture_diameter_m``. Values that are not positive
        numbers are left for the section's validation to name.

    Raises
    ------
    UserError
        One line naming both values: ``focal_length_m / pixel_pitch_m`` against the camera's focal length,
        or ``f_number`` against the camera's ``f / D``.
    """
    from renderlab.sensor.model import SensorOptions, pixel_solid_angle_sr

    out = dict(sensor)
    pitch = out.get("pixel_pitch_m", SensorOptions.__dataclass_fields__["pixel_pitch_m"].default)
    if "focal_length_m" not in out and "aperture_diameter_m" not in out:
        return out
    given = [out[k] for k in ("focal_length_m", "aperture_diameter_m", "f_number") if k in out]
    if not all(_positive(v) for v in (pitch, fx, fy, *given)):
        return out
    focal_px = pixel_solid_angle_sr(fx, fy, skew, skew_yx) ** -0.5
    if "focal_length_m" in out:
        f = out.pop("focal_length_m")
        if abs(f / pitch - focal_px) > 1e-3 * focal_px:
            raise UserError(f"sensor.focal_length_m / sensor.pixel_pitch_m = {f:g} m / {pitch:g} m = "
                            f"{f / pitch:.6g} px disagrees with the camera's focal length sqrt(camera.fx * "
                            f"camera.fy) = {focal_px:.6g} px; drop sensor.focal_length_m (the camera's is used)")
    if "aperture_diameter_m" in out:
        n_cam = focal_px * pitch / out.pop("aperture_diameter_m")
        n = out.setdefault("f_number", n_cam)
        if abs(n - n_cam) > 1e-3 * n:
            raise UserError(f"sensor.f_number = {n:g} disagrees with the camera's focal length / "
                            f"sensor.aperture_diameter_m = f/{n_cam:.6g}; give one of them")
    return out
