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

from renderlab.errors import UserError
from renderlab.measurement.apriori import AprioriImage, read_apriori  # noqa: F401  (re-exported)

IMAGE_SUFFIXES = (".png", ".tif", ".tiff", ".fits", ".fit", ".fts")


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


def measure_images(apriori_path: Path, maplets: list, method, options, *, allow_reference: bool = False,
                   progress: bool = False):
    """The measurement table of the images listed in the a-priori file (truth columns NaN)."""
    from tqdm import tqdm

    from renderlab.contracts.landmark import CameraPose
    from renderlab.contracts.schemas import LANDMARK_RUNNER, table_from_rows
    from renderlab.measurement.runner import make_method, run_method_on_image

    from renderlab.measurement.apriori import check_image_sizes

    camera, adc_max, _, images = read_apriori(apriori_path)
    check_image_sizes(camera, images, read_image)  # every file reads, at the camera's size, before anything is measured
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
