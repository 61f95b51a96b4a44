"""The agreement measures of the cross-renderer check (:mod:`renderlab.crosscheck`): per frame, radiometric,
geometric and shadow-edge agreement of a Mitsuba and a Cycles render of the same frame, the row they fill
(:class:`FrameAgreement`) and the targets."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from renderlab.geometry.camera import CameraModel

LIT_FRACTION = 0.02
TARGETS = {"rad_median_rel": 0.01, "geo_max_px": 0.05, "shadow_p99_px": 0.5}


@dataclass
class FrameAgreement:
    """Agreement of one frame (NaN where a check has no pixels)."""

    frame: int
    time_s: float
    id_agreement: float
    n_lit: int
    n_lit_one_only: int
    rad_median_rel: float
    rad_p99_rel: float
    n_geo: int
    geo_median_px: float
    geo_max_px: float
    range_rel_median: float
    range_rel_max: float
    reproj_mitsuba_max_px: float
    reproj_cycles_max_px: float
    n_landmarks: int
    lmk_max_px: float
    n_shadow_edge: int
    shadow_median_px: float
    shadow_p99_px: float
    n_oracle: int = 0
    oracle_mitsuba_off: int = -1
    oracle_cycles_off: int = -1
    oracle_both_ok: int = -1
    edge_vs_oracle_mitsuba_p99_px: float = float("nan")
    edge_vs_oracle_cycles_p99_px: float = float("nan")


def _stat(x, fn) -> float:
    return float(fn(x)) if len(x) else float("nan")


def _luminance(tf) -> np.ndarray:
    return (tf.radiance if tf.radiance is not None else tf.rgb.mean(axis=-1)).astype(np.float64)


def radiometric_agreement(Lm: np.ndarray, Lc: np.ndarray, lit_fraction: float = LIT_FRACTION):
    """(lit mask, relative differences |Lc/Lm − 1| over it)."""
    ref = np.percentile(Lm, 99.9)
    lit = (Lm >= lit_fraction * ref) & (Lc >= lit_fraction * ref) & (ref > 0)
    return lit, np.abs(Lc[lit] / Lm[lit] - 1.0)


def reprojection_px(P: np.ndarray, camera, pose, sl: np.ndarray) -> np.ndarray:
    """Pixel distance between the projection of render-frame points P (N, 3) and pixels sl (N, 2)."""
    R = pose["R_render_from_cam"]
    pc = (P - pose["position_m"]) @ R
    return np.linalg.norm(camera.project(pc) - sl, axis=1)


def position_gap(Pm: np.ndarray, Pc: np.ndarray, camera, pose) -> tuple[np.ndarray, np.ndarray]:
    """Gap between two renderers' hit points: (f·|ΔP⊥|/range in px across the line of sight,
    |Δrange|/range along it)."""
    ray = Pm - pose["position_m"]
    rng = np.linalg.norm(ray, axis=1)
    u = ray / rng[:, None]
    d = Pc - Pm
    along = np.einsum("ij,ij->i", d, u)
    perp = np.linalg.norm(d - along[:, None] * u, axis=1)
    f = max(float(camera.fx), float(camera.fy))
    return f * perp / rng, np.abs(along) / rng


def shadow_edge_shift_px(Lm, Lc, ids_m, ids_c, normal, sun_dir):
    """(edge mask, shift in px) of cast-shadow edges between two box-filtered images.

    An edge pixel has, within its 5×5 neighbourhood (all on one body in both images), a bright pixel
    (> ½ of the local maximum) and a dark pixel (< 0.1 of it) whose normal faces the sun (cast shadow,
    not the terminator), and a lit fraction f = (L − min)/(max − min) strictly inside (0.02, 0.98) in
    either image. Its shift is |Σ (L_c − L_m)| / (max − min) summed over the pixel and its two
    neighbours along the dominant gradient axis: exact for an edge along a pixel axis moved by less
    than 1 px (the moved area is split over at most two adjacent pixels), an overestimate by up to √2
    for oblique edges.
    """
    same = (ids_m == ids_c) & (ids_m >= 0)
    one_body = (ndimage.minimum_filter(ids_m, 5) == ndimage.maximum_filter(ids_m, 5)) & \
        (ndimage.minimum_filter(np.where(same, 1, 0), 5) > 0)
    hi, lo = ndimage.maximum_filter(Lm, 5), ndimage.minimum_filter(Lm, 5)
    step = hi - lo
    mu0 = np.nan_to_num(normal @ np.asarray(sun_dir, float), nan=-1.0)
    dark_facing = (Lm < 0.1 * hi) & (mu0 > 0.2)
    near_dark = ndimage.maximum_filter(dark_facing.astype(np.uint8), 5) > 0
    near_bright = ndimage.maximum_filter((Lm > 0.5 * hi).astype(np.uint8), 5) > 0
    with np.errstate(divide="ignore", invalid="ignore"):
        fm, fc = (Lm - lo) / step, (Lc - lo) / step
    partial = ((fm > 0.02) & (fm < 0.98)) | ((fc > 0.02) & (fc < 0.98))
    edge = one_body & near_dark & near_bright & partial & (step > 0)
    edge[:2, :] = edge[-2:, :] = False
    edge[:, :2] = edge[:, -2:] = False
    diff = Lc - Lm
    gy, gx = np.gradient(Lm)
    sum_x = np.roll(diff, 1, 1) + diff + np.roll(diff, -1, 1)
    sum_y = np.roll(diff, 1, 0) + diff + np.roll(diff, -1, 0)
    moved = np.where(np.abs(gx) >= np.abs(gy), sum_x, sum_y)
    return edge, np.abs(moved[edge]) / step[edge]


def frame_agreement(fm, fc, landmarks=None) -> tuple[FrameAgreement, dict]:
    """Agreement of one frame of the Mitsuba (``fm``) and Cycles (``fc``) truth sets (TruthFrame)."""
    from scipy.spatial.transform import Rotation


    meta = fm.meta
    camera = CameraModel.from_dict(meta["camera"])
    pose = {"position_m": np.asarray(meta["pose"]["position_m"], float),
            "R_render_from_cam": Rotation.from_quat(meta["pose"]["quat_render_from_cam_xyzw"]).as_matrix()}
    Lm, Lc = _luminance(fm), _luminance(fc)
    lit, rel = radiometric_agreement(Lm, Lc)
    ref = np.percentile(Lm, 99.9)
    one_only = ((Lm >= LIT_FRACTION * ref) & (Lc < 0.1 * Lm)) | ((Lc >= LIT_FRACTION * ref) & (Lm < 0.1 * Lc))

    H, W = fm.id.shape
    ll, ss = np.mgrid[0:H, 0:W]
    hit = (fm.id == fc.id) & (fm.id >= 0)
    sl = np.column_stack([ss[hit], ll[hit]]).astype(float)
    Pm, Pc = fm.position[hit].astype(np.float64), fc.position[hit].astype(np.float64)
    gap, depth = position_gap(Pm, Pc, camera, pose)
    rep_m = reprojection_px(Pm, camera, pose, sl)
    rep_c = reprojection_px(Pc, camera, pose, sl)
    gap_img = np.full((H, W), np.nan)
    gap_img[hit] = gap

    lmk = np.zeros(0)
    if landmarks is not None and len(landmarks):
        s = np.clip(np.rint(landmarks["s"]).astype(int), 0, W - 1)
        line = np.clip(np.rint(landmarks["l"]).astype(int), 0, H - 1)
        ok = hit[line, s]
        lmk = gap_img[line[ok], s[ok]]

    sun = np.asarray(meta["sun"]["direction_render"], float)
    edge, shift = shadow_edge_shift_px(Lm, Lc, fm.id, fc.id, fm.normal.astype(np.float64), sun)
    rel_img = np.full((H, W), np.nan)
    rel_img[lit] = Lc[lit] / Lm[lit] - 1.0
    shift_img = np.full((H, W), np.nan)
    shift_img[edge] = shift
    row = FrameAgreement(
        frame=int(fm.index), time_s=float(fm.time_s), id_agreement=float(np.mean(fm.id == fc.id)),
        n_lit=int(lit.sum()), n_lit_one_only=int(one_only.sum()), rad_median_rel=_stat(rel, np.median), rad_p99_rel=_stat(rel, lambda x: np.percentile(x, 99)),
        n_geo=int(hit.sum()), geo_median_px=_stat(gap, np.median), geo_max_px=_stat(gap, np.max),
        range_rel_median=_stat(depth, np.median), range_rel_max=_stat(depth, np.max),
        reproj_mitsuba_max_px=_stat(rep_m, np.max), reproj_cycles_max_px=_stat(rep_c, np.max),
        n_landmarks=int(len(lmk)), lmk_max_px=_stat(lmk, np.max),
        n_shadow_edge=int(edge.sum()), shadow_median_px=_stat(shift, np.median),
        shadow_p99_px=_stat(shift, lambda x: np.percentile(x, 99)),
    )
    step = ndimage.maximum_filter(Lm, 5) - ndimage.minimum_filter(Lm, 5)
    return row, {"Lm": Lm, "Lc": Lc, "rel": rel_img, "gap": gap_img, "shift": shift_img, "one_only": one_only,
                 "edge": edge, "step": step}
