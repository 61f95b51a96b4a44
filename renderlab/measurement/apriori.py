"""The a-priori file of ``renderlab measure --images``: its schema, reader, checks and an exporter from a truth set.

The file is JSON; its schema is the pydantic model :class:`AprioriFile` (the camera, the sensor's bits, the body
frame and one entry per image with the onboard system's belief: pose, covariance, sun). Its reference,
``docs/apriori_file.md``, is generated from the models::

    python -m renderlab.measurement.apriori           # rewrite docs/apriori_file.md
    python -m renderlab.measurement.apriori --check   # exit 1 if it is stale

What the reader checks beyond the schema: the images exist and each one's size equals the camera's
(:func:`check_image_sizes`), and ``frame`` names the catalogue's frame when the catalogue folder is a truth set
that records one (:func:`check_frame`). :func:`write_apriori` (``renderlab export TRUTHSET --apriori FILE``) writes
the file for a truth set's own images, so a user can start from a working one.
"""

from __future__ import annotations

import json
import math
import os
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
import pydantic
from pydantic import Field, model_validator

from renderlab.contracts.config_types import Finite, NonNegative, Positive, Strict, Vec3
from renderlab.errors import UserError
from renderlab.files.truthset import TruthSet
from renderlab.geometry.calibration import read_calibration
from renderlab.geometry.camera import CameraModel
from renderlab.geometry.rotations import rotation_from_quat_xyzw
from renderlab.measurement.runner import MeasureOptions, draw_apriori
from renderlab.scenario import keyref

DOC = Path(__file__).resolve().parents[2] / "docs" / "apriori_file.md"
REGENERATE = "python -m renderlab.measurement.apriori"
Sigma3 = Annotated[list[NonNegative], Field(min_length=3, max_length=3)]
Quat = Annotated[list[Finite], Field(min_length=4, max_length=4)]


class AprioriCamera(Strict):
    """The believed camera of every image: intrinsics (as a truth set's manifest writes them), or an OpenCV
    (``cv2.FileStorage`` YAML/JSON) / ROS ``camera_info`` calibration file."""

    calibration_file: str | None = Field(None, description="Calibration file, relative to the a-priori file's "
                                         "folder; sets every intrinsic (not with fx, fy, cx, cy, model, distortion)")
    width: Annotated[int, Field(gt=0, le=16384)] | None = Field(None, description="Image width, 1..16384; every "
                                                                "image must be this wide (optional with a calibration file "
                                                                "that has it) [px]")
    height: Annotated[int, Field(gt=0, le=16384)] | None = Field(None, description="Image height [px]")
    fx: Positive | None = Field(None, description="Focal length along image x (columns) [px]")
    fy: Positive | None = Field(None, description="Focal length along image y (rows) [px]")
    cx: Finite | None = Field(None, description="Principal point x; (0, 0) is the top-left pixel's centre [px]")
    cy: Finite | None = Field(None, description="Principal point y [px]")
    skew: Finite = Field(0.0, description="Off-diagonal K[0, 1] (OpenCV's skew) [px]")
    skew_yx: Finite = Field(0.0, description="Off-diagonal K[1, 0] (the Retina/Owen Kyx term) [px]")
    model: Literal["pinhole", "brown", "owen", "opencv", "kannala_brandt"] | None = Field(
        None, description="Distortion model (renderlab.geometry.camera.CameraModel); default pinhole")
    distortion: dict[str, Finite] | None = Field(None, description="Coefficients by name, missing ones 0 (as in "
                                                 "the scenario key camera.distortion)")

    @model_validator(mode="after")
    def _one_source(self):
        given = [k for k in ("fx", "fy", "cx", "cy", "model", "distortion") if getattr(self, k) is not None]
        if self.calibration_file is not None:
            if given:
                raise ValueError(f"calibration_file and {given[0]} are both given; the calibration file sets the "
                                 "intrinsics")
        else:
            missing = [k for k in ("width", "height", "fx", "fy", "cx", "cy") if getattr(self, k) is None]
            if missing:
                raise ValueError(f"{missing[0]} is missing (give the intrinsics or a calibration_file)")
        return self


class AprioriImageEntry(Strict):
    """One image and what the onboard system believes when it is taken (pose ``p_body = R(q) p_cam + position_m``,
    camera +z boresight, +x toward increasing sample, +y toward increasing line). Give either ``covariance`` or
    both sigma lists."""

    file: str = Field(min_length=1, description="Image file, relative to the a-priori file's folder: PNG or TIFF "
                      "(8- or 16-bit grey, read unchanged) or FITS (first 2-D HDU); its size must be the camera's")
    epoch_utc: str = Field("", description="Epoch, ISO 8601 UTC (copied to the table's epoch_utc column)")
    position_m: Vec3 = Field(description="A-priori camera position in the body frame [m]")
    quat_body_from_cam_xyzw: Quat = Field(description="A-priori attitude, scalar-last unit quaternion of "
                                          "R_body_from_cam")
    sun_direction_body: Vec3 = Field(description="Direction toward the Sun in the body frame (any length > 0)")
    covariance: Annotated[list[Annotated[list[Finite], Field(min_length=6, max_length=6)]],
                          Field(min_length=6, max_length=6)] | None = Field(
        None, description="6×6 a-priori covariance of [position (m), attitude small rotation about the body-from-"
        "camera rotation (rad)], symmetric positive semi-definite")
    position_sigma_m: Sigma3 | None = Field(None, description="A-priori position 1σ per body axis (instead of "
                                            "covariance) [m]")
    attitude_sigma_deg: Sigma3 | None = Field(None, description="A-priori attitude 1σ per axis (instead of "
                                              "covariance) [deg]")

    @model_validator(mode="after")
    def _uncertainty(self):
        if np.linalg.norm(self.sun_direction_body) == 0:
            raise ValueError("sun_direction_body must be non-zero")
        sig = (self.position_sigma_m is not None, self.attitude_sigma_deg is not None)
        if self.covariance is not None:
            if any(sig):
                raise ValueError("give either covariance or position_sigma_m + attitude_sigma_deg, not both")
            c = np.asarray(self.covariance, float)
            scale = max(float(np.abs(c).max()), 1e-300)
            if not np.allclose(c, c.T, rtol=0, atol=1e-12 * scale):
                raise ValueError("covariance must be symmetric")
            if np.linalg.eigvalsh(c).min() < -1e-12 * scale:
                raise ValueError("covariance is not positive semi-definite")
        elif not all(sig):
            raise ValueError("needs covariance, or both position_sigma_m and attitude_sigma_deg")
        return self


class AprioriFile(Strict):
    """The a-priori file of ``renderlab measure --images`` (JSON)."""

    camera: AprioriCamera = Field(description="The believed camera model of every image")
    bits: Annotated[int, Field(ge=1, le=32)] | None = Field(None, description="Sensor bits, 1..32: pixels at 2**bits − 1 "
                                                            "are saturated and not used; absent: every pixel is used")
    frame: str = Field(min_length=1, description="Name of the body frame the poses, the sun and the catalogue are "
                       "in; must equal the catalogue's when its folder is a truth set that records it (EV5: "
                       "EV5_FIXED)")
    images: Annotated[list[AprioriImageEntry], Field(min_length=1)] = Field(description="The images, measured "
                                                                            "in this order (frame = position)")


@dataclass(frozen=True)
class AprioriImage:
    """One image and its a-priori knowledge (body frame)."""

    index: int
    path: Path
    epoch_utc: str
    R_body_from_cam: np.ndarray
    position_m: np.ndarray
    sun_body: np.ndarray
    cov_pos_m2: np.ndarray
    cov_att_rad2: np.ndarray


def _error_line(err: pydantic.ValidationError, source: str) -> str:
    e = err.errors()[0]
    loc = ".".join(str(p) for p in e["loc"] if not str(p).startswith("function-"))
    msg = e["msg"].removeprefix("Value error, ")
    if e["type"] == "extra_forbidden":
        return f"{source}: unknown key '{loc}' (the format: docs/apriori_file.md)"
    if e["type"] == "missing":
        return f"{source}: missing key '{loc}' (the format: docs/apriori_file.md)"
    got = e.get("input")
    got_txt = "" if isinstance(got, (dict, list)) or got is None else f" (got {got!r})"
    return f"{source}: {loc + ': ' if loc else ''}{msg}{got_txt}"


def _camera(cam: AprioriCamera, base: Path, source: str):
    d = cam.model_dump(exclude_none=True)
    if cam.calibration_file is not None:
        try:
            cal = read_calibration(base / cam.calibration_file)
        except UserError as err:
            raise UserError(f"{source}: camera.calibration_file: {err}") from None
        for key in ("width", "height"):
            if key in cal and key in d and cal[key] != d[key]:
                raise UserError(f"{source}: camera.{key} = {d[key]} but the calibration file is for {cal[key]}")
            if key not in cal and key not in d:
                raise UserError(f"{source}: camera.calibration_file has no image_{key}; give camera.{key}")
        d = {**{k: v for k, v in d.items() if k != "calibration_file"}, **cal}
    try:
        return CameraModel.from_dict(d)
    except (UserError, ValueError) as err:
        raise UserError(f"{source}: camera: {err}") from None


def read_apriori(path: Path, base: Path | None = None):
    """(CameraModel, adc_max or None, frame name, [AprioriImage]) from an a-priori file (:class:`AprioriFile`);
    one-line :class:`UserError` on anything the schema refuses."""
    path = Path(path)
    if not path.is_file():
        raise UserError(f"a-priori file not found: {path}")
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (ValueError, UnicodeDecodeError) as exc:
        raise UserError(f"{path.name}: not valid JSON ({exc})") from None
    if not isinstance(data, dict):
        raise UserError(f"{path.name}: must be a JSON object (the format: docs/apriori_file.md)")
    try:
        doc = AprioriFile.model_validate(data)
    except pydantic.ValidationError as err:
        raise UserError(_error_line(err, path.name)) from None
    base = Path(base) if base is not None else path.parent
    camera = _camera(doc.camera, path.parent, path.name)
    out = []
    for k, d in enumerate(doc.images):
        R = rotation_from_quat_xyzw(d.quat_body_from_cam_xyzw, f"{path.name}: images[{k}]").as_matrix()
        if d.covariance is not None:
            c = np.asarray(d.covariance, float)
            cp, ca = c[:3, :3], c[3:, 3:]
        else:
            sp, sa = np.asarray(d.position_sigma_m), np.radians(d.attitude_sigma_deg)
            cp, ca = np.diag(sp * sp), np.diag(sa * sa)
        sun = np.asarray(d.sun_direction_body, float)
        out.append(AprioriImage(k, base / d.file, d.epoch_utc, R, np.asarray(d.position_m, float),
                                sun / np.linalg.norm(sun), cp, ca))
    return camera, ((1 << doc.bits) - 1 if doc.bits else None), doc.frame, out


def catalogue_frame(catalog_dir: Path) -> str | None:
    """The frame name a catalogue folder records (a truth set's ``manifest.json`` ``render_frame.name``), or None."""
    m = Path(catalog_dir) / "manifest.json"
    if not m.is_file():
        return None
    try:
        rf = json.loads(m.read_text(encoding="utf-8")).get("render_frame")
    except (ValueError, UnicodeDecodeError, AttributeError):
        return None
    return rf.get("name") if isinstance(rf, dict) and isinstance(rf.get("name"), str) else None


def check_frame(frame: str, catalog_dir: Path, source: str) -> None:
    """Refuse an a-priori ``frame`` that is not the catalogue's (when the catalogue records one)."""
    want = catalogue_frame(catalog_dir)
    if want is not None and frame != want:
        raise UserError(f"{source}: frame is {frame!r} but the catalogue in {catalog_dir} is in {want!r} (poses, "
                        "sun and landmarks must be in one body frame)")


def check_image_sizes(camera, images, read) -> None:
    """Every image exists and is ``camera.width`` × ``camera.height``; ``read(path) -> (H, W) array``."""
    for im in images:
        if not im.path.is_file():
            raise UserError(f"image not found: {im.path}")
        h, w = np.shape(read(im.path))[:2]
        if (w, h) != (camera.width, camera.height):
            raise UserError(f"{im.path.name} is {w}x{h} px but the a-priori camera is {camera.width}x"
                            f"{camera.height} px (the camera must be the one the images were taken with)")


# ------------------------------------------------------------------------------------------- exporter
def write_apriori(truthset, out: Path, *, position_sigma_m: float = 0.5, attitude_sigma_deg: float = 0.05,
                  seed: int | None = None, overwrite: bool = False) -> int:
    """Write the a-priori file of a truth set's own DN images (``frames/NNNNNN.png``); return the image count.

    Parameters
    ----------
    truthset : str or Path
        Truth-set folder; every frame must share one camera.
    out : Path
        The JSON file; image paths in it are relative to its folder.
    position_sigma_m, attitude_sigma_deg : float
        The declared a-priori 1σ per axis.
    seed : int, optional
        None: the a-priori pose is the true pose. An integer: the true pose perturbed by one draw per frame from
        ``numpy.random.default_rng(seed)``, exactly as ``renderlab measure TRUTHSET --seed`` draws it
        (:func:`renderlab.measurement.runner.draw_apriori`), so both measure the same poses.
    overwrite : bool
        Replace an existing ``out``.
    """
    from scipy.spatial.transform import Rotation


    out = Path(out)
    for name, v in (("position_sigma_m", position_sigma_m), ("attitude_sigma_deg", attitude_sigma_deg)):
        if not (math.isfinite(v) and v >= 0):
            raise UserError(f"{name} must be a finite non-negative number, got {v}")
    if out.exists() and not overwrite:
        raise UserError(f"output {out} exists (use --overwrite to replace it)")
    if not out.parent.is_dir():
        raise UserError(f"cannot write {out}: directory {out.parent} does not exist")
    ts = TruthSet.open(truthset)
    if not ts.frames:
        raise UserError(f"truth set {ts.path} has no frames")
    cams = [ts.camera(i) for i in range(len(ts))]
    if any(c != cams[0] for c in cams):
        raise UserError(f"truth set {ts.path}: the frames have different cameras; an a-priori file has one")
    opts = MeasureOptions(sigma_pos_m=(position_sigma_m,) * 3, sigma_att_rad=(math.radians(attitude_sigma_deg),) * 3)
    rng = None if seed is None else np.random.default_rng(seed)
    images = []
    for i, rec in enumerate(ts.frames):
        q, pos = rec["pose"]["quat_render_from_cam_xyzw"], np.asarray(rec["pose"]["position_m"], float)
        if rng is not None:
            R, pos, _, _ = draw_apriori(rotation_from_quat_xyzw(q, f"frames[{i}]").as_matrix(), pos, opts, rng)
            q = Rotation.from_matrix(R).as_quat()
        images.append({"file": Path(os.path.relpath(ts.path.resolve() / rec["dn"], out.parent.resolve())).as_posix(),
                       "epoch_utc": str(rec.get("epoch_utc", "")), "position_m": [float(x) for x in pos],
                       "quat_body_from_cam_xyzw": [float(x) for x in q],
                       "sun_direction_body": [float(x) for x in rec["sun"]["direction_render"]],
                       "position_sigma_m": [float(position_sigma_m)] * 3,
                       "attitude_sigma_deg": [float(attitude_sigma_deg)] * 3})
    bits = (ts.frames[0].get("sensor") or {}).get("bits")
    doc = {"camera": cams[0], **({"bits": int(bits)} if bits else {}),
           "frame": (ts.manifest.get("render_frame") or {}).get("name") or "BODY", "images": images}
    AprioriFile.model_validate(doc)  # what is written reads back
    tmp = out.with_name(f".{out.name}.tmp-{os.getpid()}")
    try:
        tmp.write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
        os.replace(tmp, out)
    finally:
        tmp.unlink(missing_ok=True)
    return len(images)


# ------------------------------------------------------------------------------------------- reference
def render() -> str:
    """``docs/apriori_file.md``: one table per object of the format, from the models' field descriptions."""
    lines = ["# The a-priori file of `renderlab measure --images`", "",
             f"Generated from the pydantic models of `renderlab.measurement.apriori` by `{REGENERATE}`; do not edit "
             "by hand (`tests/test_apriori_file.py` fails when it is stale).", "",
             "A JSON object. `renderlab export TRUTHSET --apriori FILE` writes one for a truth set's own images "
             "(`--apriori-seed S` draws the a-priori pose as `renderlab measure TRUTHSET --seed S` does). Checked "
             "when read, before anything is measured or written: the schema below (unknown keys refused), every "
             "image exists and has the camera's width × height, and `frame` equals the catalogue's frame when "
             "`--catalog` is a truth set that records one. Example:", "", "```json",
             EXAMPLE, "```", ""]
    for title, model in (("Top level", AprioriFile), ("`camera`", AprioriCamera), ("`images[i]`", AprioriImageEntry)):
        lines += [f"## {title}", "", keyref._rst((model.__doc__ or "").strip()), "",
                  "| key | type | default | allowed | unit | description |", "|---|---|---|---|---|---|"]
        for name, f in model.model_fields.items():
            desc, unit = keyref.split_unit(keyref._rst(f.description or ""))
            row = (f"`{name}`", keyref._type_text(f.annotation).replace("table", "object"), keyref._default(f), keyref._allowed(f), unit, desc)
            lines.append("| " + " | ".join(c.replace("|", "\\|") for c in row) + " |")
        lines.append("")
    return "\n".join(lines)


EXAMPLE = """{"camera": {"width": 1024, "height": 1024, "fx": 2000.0, "fy": 2000.0, "cx": 511.5, "cy": 511.5},
 "bits": 12,
 "frame": "EV5_FIXED",
 "images": [{"file": "img_000.png", "epoch_utc": "2026-12-02T00:00:00Z",
             "position_m": [0.0, 0.0, 200.0], "quat_body_from_cam_xyzw": [1.0, 0.0, 0.0, 0.0],
             "sun_direction_body": [0.3, 0.2, 0.93],
             "position_sigma_m": [0.5, 0.5, 0.5], "attitude_sigma_deg": [0.05, 0.05, 0.05]}]}"""


def main(argv: list[str] | None = None) -> int:
    """``python -m renderlab.measurement.apriori [--check]``."""
    args = sys.argv[1:] if argv is None else argv
    text = render()
    if "--check" in args:
        same = DOC.is_file() and DOC.read_text(encoding="utf-8") == text
        print(f"{DOC}: {'up to date' if same else f'stale; regenerate with {REGENERATE}'}")
        return 0 if same else 1
    DOC.write_text(text, encoding="utf-8")
    print(f"wrote {DOC}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
