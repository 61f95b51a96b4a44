"""Measure landmarks in a user's own images: plain image files + an a-priori file + a maplet catalogue, no truth set.

The a-priori file (JSON) holds the camera and, per image, what the onboard system believes::

    {"camera": {"model": "pinhole", "width": 1024, "height": 1024, "fx": ..., "fy": ..., "cx": ..., "cy": ...,
                "distortion": {...}},            # or "calibration_file": "cam.yaml" (OpenCV / ROS), see geometry
     "bits": 12,                                 # optional: saturation level 2**bits - 1 (pixels at it are unused)
     "frame": "EV5_FIXED",                       # the body frame the poses, the sun and the catalogue are in
     "images": [{"file": "img_000.png", "epoch_utc": "2026-01-01T00:00:00Z",
                 "position_m": [x, y, z], "quat_body_from_cam_xyzw": [qx, qy, qz, qw],
                 "sun_direction_body": [sx, sy, sz],
                 "covariance": 6×6 [position m, attitude rad] or
                 "position_sigma_m": [.., .., ..], "attitude_sigma_deg": [.., .., ..]}, ...]}

Poses follow the lab's convention ``p_body = R(q) p_cam + position_m`` (scalar-last quaternion; camera +z
boresight, +x toward increasing sample, +y toward increasing line). Images: PNG or TIFF (8- or 16-bit grey, read
with OpenCV unchanged) or FITS (astropy, first image HDU). The measurement table has the usual schema with the truth
columns and the a-priori draw NaN (``err = meas − truth`` is unknown).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from renderlab.errors import UserError

IMAGE_SUFFIXES = (".png", ".tif", ".tiff", ".fits", ".fit", ".fts")


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


def read_image(path: Path) -> np.ndarray:
    """A grey image as float64 (PNG/TIFF through OpenCV unchanged, FITS through astropy)."""
    path = Path(path)
    if not path.is_file():
        raise UserError(f"image not found: {path}")
    if path.suffix.lower() in (".fits", ".fit", ".fts"):
        from astropy.io import fits

        try:
            with fits.open(path) as hdul:
                data = next((h.data for h in hdul if getattr(h, "data", None) is not None and h.data.ndim == 2), None)
        except (OSError, ValueError) as exc:
            raise UserError(f"cannot read FITS image {path.name}: {exc}") from None
        if data is None:
            raise UserError(f"{path.name}: no 2-D image HDU")
        return np.asarray(data, np.float64)
    import cv2

    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise UserError(f"cannot read image {path.name} (PNG/TIFF 8- or 16-bit grey, or FITS)")
    if img.ndim == 3:
        raise UserError(f"{path.name}: a grey image is needed, got {img.shape[2]} channels")
    return img.astype(np.float64)


def _vec(d: dict, key: str, n: int, where: str) -> np.ndarray:
    v = np.asarray(d.get(key, []), float)
    if v.shape != (n,) or not np.all(np.isfinite(v)):
        raise UserError(f"{where}: '{key}' must be {n} finite numbers")
    return v


def _covariances(d: dict, where: str) -> tuple[np.ndarray, np.ndarray]:
    if "covariance" in d:
        c = np.asarray(d["covariance"], float)
        if c.shape != (6, 6) or not np.all(np.isfinite(c)) or not np.allclose(c, c.T, atol=1e-12 * np.abs(c).max()):
            raise UserError(f"{where}: 'covariance' must be a finite symmetric 6×6 matrix [position m, attitude rad]")
        if np.linalg.eigvalsh(c).min() < -1e-12 * np.abs(c).max():
            raise UserError(f"{where}: 'covariance' is not positive semi-definite")
        return c[:3, :3], c[3:, 3:]
    sp = _vec(d, "position_sigma_m", 3, where)
    sa = np.radians(_vec(d, "attitude_sigma_deg", 3, where))
    if np.any(sp < 0) or np.any(sa < 0):
        raise UserError(f"{where}: sigmas must be >= 0")
    return np.diag(sp * sp), np.diag(sa * sa)


def read_apriori(path: Path, base: Path | None = None):
    """(CameraModel, adc_max or None, frame name, [AprioriImage]) from the a-priori JSON (module docstring)."""
    from renderlab.geometry.camera import CameraModel
    from renderlab.geometry.rotations import rotation_from_quat_xyzw

    path = Path(path)
    if not path.is_file():
        raise UserError(f"a-priori file not found: {path}")
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (ValueError, UnicodeDecodeError) as exc:
        raise UserError(f"{path.name}: not valid JSON ({exc})") from None
    if not isinstance(data, dict) or not isinstance(data.get("images"), list) or not data["images"]:
        raise UserError(f"{path.name}: needs a non-empty 'images' list")
    if not isinstance(data.get("camera"), dict):
        raise UserError(f"{path.name}: needs a 'camera' table")
    camera = CameraModel.from_dict(data["camera"])
    bits = data.get("bits")
    if bits is not None and (isinstance(bits, bool) or not isinstance(bits, int) or not 1 <= bits <= 32):
        raise UserError(f"{path.name}: 'bits' must be an integer in 1..32")
    base = Path(base) if base is not None else path.parent
    out = []
    for k, d in enumerate(data["images"]):
        where = f"{path.name}: images[{k}]"
        if not isinstance(d, dict) or not isinstance(d.get("file"), str):
            raise UserError(f"{where}: needs 'file'")
        R = rotation_from_quat_xyzw(_vec(d, "quat_body_from_cam_xyzw", 4, where), where).as_matrix()
        sun = _vec(d, "sun_direction_body", 3, where)
        if not np.linalg.norm(sun) > 0:
            raise UserError(f"{where}: 'sun_direction_body' must be non-zero")
        cp, ca = _covariances(d, where)
        out.append(AprioriImage(k, base / d["file"], str(d.get("epoch_utc", "")), R, _vec(d, "position_m", 3, where),
                                sun / np.linalg.norm(sun), cp, ca))
    return camera, ((1 << bits) - 1 if bits else None), str(data.get("frame", "BODY")), out


def measure_images(apriori_path: Path, maplets: list, method, options, *, allow_reference: bool = False,
                   progress: bool = False):
    """The measurement table of the images listed in the a-priori file (truth columns NaN)."""
    from tqdm import tqdm

    from renderlab.contracts.landmark import CameraPose
    from renderlab.contracts.schemas import LANDMARK_RUNNER, table_from_rows
    from renderlab.measurement.runner import make_method, run_method_on_image

    camera, adc_max, _, images = read_apriori(apriori_path)
    for im in images:  # every file exists and reads before anything is measured or written
        if not im.path.is_file():
            raise UserError(f"image not found: {im.path}")
    if not maplets:
        raise UserError("the landmark catalogue is empty")
    impl = make_method(method, options, (), allow_reference=allow_reference)
    centres = np.array([m.center_m for m in maplets], float)
    nan3 = (math.nan,) * 3
    rows = []
    for im in tqdm(images, desc=f"measure {impl.name}", unit="image", disable=not progress):
        pose = CameraPose(im.R_body_from_cam, im.position_m)
        attempt, results = run_method_on_image(impl, read_image(im.path), adc_max, camera, pose, im.sun_body, maplets,
                                               centres, im.cov_pos_m2, im.cov_att_rad2, options, im.index)
        sig_p, sig_a = np.sqrt(np.diag(im.cov_pos_m2)), np.sqrt(np.diag(im.cov_att_rad2))
        for k, res in zip(attempt, results):
            ok = res.has_result
            rows.append({
                "campaign": options.campaign, "run": int(options.run), "frame": im.index,
                "item": int(maplets[k].landmark_id), "method": impl.name, "pred_s": res.pred_s, "pred_l": res.pred_l,
                "meas_s": res.meas_s if ok else math.nan, "meas_l": res.meas_l if ok else math.nan,
                "truth_s": math.nan, "truth_l": math.nan, "err_s": math.nan, "err_l": math.nan,
                "score": float(res.score), "has_result": ok, "reason": res.reason, "outlier": bool(res.outlier),
                "diagnostics": res.diagnostics, "t_ms": float(res.t_ms), "peak": str(getattr(impl, "peak", "") or ""),
                "search_px": int(res.search_px), "n_pixels": int(res.n_pixels),
                "pred_shadow_fraction": float(res.shadow_fraction), "truth_visible": None,
                **{f"apriori_dpos_{a}_m": v for a, v in zip("xyz", nan3)},
                **{f"apriori_drot_{a}_rad": v for a, v in zip("xyz", nan3)},
                **{f"apriori_sigma_pos_{a}_m": float(v) for a, v in zip("xyz", sig_p)},
                **{f"apriori_sigma_att_{a}_rad": float(v) for a, v in zip("xyz", sig_a)},
                "n_sigma": float(options.n_sigma), "gsd_ratio": math.nan, "phase_deg": math.nan,
                "incidence_deg": math.nan, "emission_deg": math.nan, "shadow_fraction": math.nan,
                "photometry": "fixed", "image": im.path.name, "epoch_utc": im.epoch_utc})
    return table_from_rows(rows, LANDMARK_RUNNER, "landmark") if rows else LANDMARK_RUNNER.empty_table()
