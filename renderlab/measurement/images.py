"""Measure landmarks in a user's own images: plain image files + an a-priori file + a maplet catalogue, no truth set.

The a-priori file (JSON) holds the camera, the body frame and, per image, what the onboard system believes (pose,
covariance, sun); its schema is :class:`renderlab.measurement.apriori.AprioriFile`, documented in
``docs/apriori_file.md``, and ``renderlab export TRUTHSET --apriori FILE`` writes one for a truth set's images.

Poses follow the lab's convention ``p_body = R(q) p_cam + position_m`` (scalar-last quaternion; camera +z
boresight, +x toward increasing sample, +y toward increasing line). Images: PNG or TIFF (8- or 16-bit grey, read
with OpenCV unchanged) or FITS (astropy, first image HDU). The measurement table has the usual schema with the truth
columns and the a-priori draw NaN (``err = meas − truth`` is unknown).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from renderlab.contracts.image_headers import check_image
from renderlab.contracts.landmark import CameraPose
from renderlab.contracts.schemas import LANDMARK_RUNNER, table_from_rows
from renderlab.errors import UserError
from renderlab.inputs import shown
from renderlab.measurement.apriori import AprioriImage, check_image_sizes, read_apriori  # noqa: F401  (re-exported)
from renderlab.measurement.runner import make_method, run_method_on_image

IMAGE_SUFFIXES = (".png", ".tif", ".tiff", ".fits", ".fit", ".fts")


def read_image(path: Path, size: tuple[int, int] | None = None) -> np.ndarray:
    """A grey image as float64 (PNG/TIFF through OpenCV unchanged, FITS through astropy). The header is checked
    first (:func:`renderlab.contracts.image_headers.check_image`: a regular file, sane sizes and, with ``size`` =
    (width, height), the camera's size), so nothing is decoded that the camera cannot have taken."""
    path = Path(path)
    hdr = check_image(path, "image", size=size)
    if hdr.kind == "fits":
        from astropy.io import fits

        try:
            with fits.open(path, memmap=False, lazy_load_hdus=True) as hdul:
                data = np.array(hdul[hdr.hdu].data, np.float64)
        except (OSError, ValueError, TypeError, IndexError) as exc:
            raise UserError(f"cannot read FITS image {shown(path)}: {' '.join(str(exc).split())[:100]}") from None
        if data.ndim != 2 or data.shape != (hdr.height, hdr.width):
            raise UserError(f"{shown(path)}: no 2-D image HDU")
        return data
    if hdr.kind not in ("png", "tiff"):
        raise UserError(f"image {shown(path)}: a {hdr.kind} file; PNG, TIFF or FITS are read")
    if hdr.channels != 1:
        raise UserError(f"{shown(path)}: a grey image is needed, got {hdr.channels} channels")
    import cv2

    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise UserError(f"cannot read image {shown(path)} (PNG/TIFF 8- or 16-bit grey, or FITS)")
    if img.ndim == 3:
        raise UserError(f"{shown(path)}: a grey image is needed, got {img.shape[2]} channels")
    return img.astype(np.float64)


def measure_images(apriori_path: Path, maplets: list, method, options, *, allow_reference: bool = False,
                   progress: bool = False):
    """The measurement table of the images listed in the a-priori file (truth columns NaN)."""
    from tqdm import tqdm




    camera, adc_max, _, images = read_apriori(apriori_path)
    for im in images:  # headers against the limits and the camera, before any image is decoded
        hdr = check_image(im.path, "image")
        if (hdr.width, hdr.height) != (camera.width, camera.height):
            raise UserError(f"{im.path.name} is {hdr.width}x{hdr.height} px but the a-priori camera is "
                            f"{camera.width}x{camera.height} px (the camera must be the one the images were taken with)")
    check_image_sizes(camera, images, read_image)  # every file reads, at the camera's size, before anything is measured
    if not maplets:
        raise UserError("the landmark catalogue is empty")
    impl = make_method(method, options, (), allow_reference=allow_reference)
    centres = np.array([m.center_m for m in maplets], float)
    nan3 = (math.nan,) * 3
    rows = []
    for im in tqdm(images, desc=f"measure {impl.name}", unit="image", disable=not progress):
        pose = CameraPose(im.R_body_from_cam, im.position_m)
        image = read_image(im.path, (camera.width, camera.height))
        attempt, results = run_method_on_image(impl, image, adc_max, camera, pose, im.sun_body, maplets,
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
