"""Self-checks of a rendered truth set against closed-form truth.

* Pixel convention: the position AOV of pixel (s, l), projected through the frame's camera
  model and pose, must land on (s, l) — the pixel centre — to ≪ 0.01 px.
* Radiometry: a Lambert surface in sunlight has radiance L = A·E·cos(i)/π with
  cos(i) = n·ŝ (n from the normal AOV, ŝ toward the sun). Checked on lit *interior* pixels
  (the pixel and its 8 neighbours hit the same body and are lit), away from silhouettes and
  shadow edges where a box-filtered pixel mixes two surfaces.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from renderlab.geometry.camera import CameraModel
from renderlab.geometry.rotations import rotation_from_quat_xyzw


@dataclass
class FrameChecks:
    frame: int
    reproj_max_px: float
    reproj_median_px: float
    n_hit: int
    lambert: dict[int, tuple[int, float, float]]  # body id → (pixels, median, p99 relative error)


def reprojection_errors(frame) -> np.ndarray:
    """|project(P_AOV) − pixel centre| (px) for every pixel that hit something."""
    cam = CameraModel.from_dict(frame.meta["camera"])
    R = rotation_from_quat_xyzw(frame.meta["pose"]["quat_render_from_cam_xyzw"]).as_matrix()
    t = np.asarray(frame.meta["pose"]["position_m"], float)
    hit = frame.id >= 0
    P = frame.position[hit].astype(np.float64)
    p_cam = (P - t) @ R  # R^T (P - t)
    sl = cam.project(p_cam)
    ll, ss = np.nonzero(hit)
    return np.hypot(sl[:, 0] - ss, sl[:, 1] - ll)


def lambert_interior_mask(frame, body_ids) -> np.ndarray:
    """Lit interior pixels of the given bodies (3×3 neighbourhood on one body, all lit)."""
    ids = frame.id
    same = np.ones(ids.shape, bool)
    for dl in (-1, 0, 1):
        for ds in (-1, 0, 1):
            same &= np.roll(np.roll(ids, dl, 0), ds, 1) == ids
    lit = frame.radiance > 0
    lit_all = ndimage.minimum_filter(lit.astype(np.uint8), size=3, mode="constant") > 0
    border = np.zeros(ids.shape, bool)
    border[1:-1, 1:-1] = True
    return same & lit_all & border & np.isin(ids, list(body_ids))


def lambert_residual_image(frame, albedo_by_id: dict[int, float]) -> np.ndarray:
    """(H, W) signed relative error L / (A·E·cos i/π) − 1 on lit interior Lambert pixels, NaN elsewhere."""
    mask = lambert_interior_mask(frame, albedo_by_id)
    sun = frame.meta["sun"]
    s = np.asarray(sun["direction_render"], float)
    n = frame.normal[mask].astype(np.float64)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    A = np.vectorize(albedo_by_id.get)(frame.id[mask])
    expected = A * sun["irradiance_w_m2"] * np.clip(n @ s, 0, None) / np.pi
    out = np.full(frame.id.shape, np.nan)
    out[mask] = frame.radiance[mask] / expected - 1.0
    return out


def lambert_relative_errors(frame, albedo_by_id: dict[int, float]) -> tuple[np.ndarray, np.ndarray]:
    """Relative errors on lit interior pixels of Lambert bodies, and the body id of each pixel."""
    res = lambert_residual_image(frame, albedo_by_id)
    mask = np.isfinite(res)
    return np.abs(res[mask]), frame.id[mask]


def check_frame(frame, albedo_by_id: dict[int, float]) -> FrameChecks:
    rep = reprojection_errors(frame)
    lam, ids = lambert_relative_errors(frame, albedo_by_id)
    per_body = {int(b): (int((ids == b).sum()), float(np.median(lam[ids == b])), float(np.percentile(lam[ids == b], 99)))
                for b in np.unique(ids)}
    return FrameChecks(
        frame=frame.index,
        reproj_max_px=float(rep.max()) if rep.size else float("nan"),
        reproj_median_px=float(np.median(rep)) if rep.size else float("nan"),
        n_hit=int(rep.size),
        lambert=per_body,
    )
