r"""Matching extracted coastline pixels to the onboard coastline database (Straub & Christian, Fig. 2b).

1. **Predict.** Database points :math:`\mathbf{o}_i` (inertial) are projected with the a-priori position
   :math:`\hat{\mathbf r}^-` and the star-tracker attitude :math:`\hat{\mathbf T}_C^I` (eqs. 14-16, then the
   camera model): :math:`\hat{\mathbf p}_i = \pi(\hat{\mathbf T}_C^I(\mathbf o_i - \hat{\mathbf r}^-))`. Points on
   the far side of the Earth (normal · (r − o) ≤ 0, sphere normal) and outside the image are dropped.
2. **Register.** A 2-D translation δ aligns the predicted curve with the extracted edge points: a coarse
   search over integer shifts within ``search_px`` minimising the truncated chamfer cost
   :math:`\sum_i \min(D(\hat{\mathbf p}_i + \delta), \tau)` on the OpenCV distance transform D of the edge
   raster, then trimmed point-to-line ICP (nearest extracted point, inliers within ``gate_px``, Huber weights
   at 0.5 px; where the coast is nearly straight and the 2-D step is ill-conditioned, δ ← δ + the median
   point-to-point residual).
   With a star-tracker attitude the a-priori error is mostly a translation of the image; rotation about the
   boresight is not estimated (a star tracker bounds it to arcseconds).
3. **Associate.** Each registered database point p̂_i + δ takes the nearest extracted point within ``gate_px``;
   its observed pixel is the foot of the perpendicular from p̂_i + δ onto the local edge line through that
   point (the across-curve part comes from the image, the along-curve part from the registration, which a
   curve cannot give point by point), so the EKF innovation (eq. 6) carries the a-priori error: across the
   curve as measured, along it as registered. Up to ``points_per_image`` pairs are kept, the one
   nearest each cell centre of a g x g grid (g² ≤ points_per_image) so they spread over the image and their
   errors are nearly independent, as eq. 18 assumes.

The observed LOS is the camera model's unit ray through the observed pixel (camera frame, eq. 16's y).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from renderlab.geometry.camera import CameraModel

__all__ = ["MatchOptions", "Match", "project_database", "register_translation", "match_coastline"]


@dataclass(frozen=True)
class MatchOptions:
    """Registration and association settings (pixels)."""

    search_px: float = 40.0
    gate_px: float = 1.5
    chamfer_cap_px: float = 6.0
    icp_iterations: int = 30
    points_per_image: int = 16
    min_inliers: int = 8


@dataclass
class Match:
    """Result for one image. ``db_index`` indexes the database points given; ``obs_sl`` their observed pixels."""

    db_index: np.ndarray
    obs_sl: np.ndarray
    pred_sl: np.ndarray
    los_cam: np.ndarray
    shift_px: np.ndarray
    n_predicted: int
    n_inliers: int
    residual_px: float
    ok: bool


def project_database(points_inertial: np.ndarray, r_inertial: np.ndarray, T_cam_from_inertial: np.ndarray,
                     camera: CameraModel, margin_px: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Predicted pixels (k, 2) of the visible database points and their indices (k,)."""
    o = np.asarray(points_inertial, np.float64)
    r = np.asarray(r_inertial, np.float64)
    facing = np.einsum("ij,ij->i", o, r - o) > 0
    p_cam = (o - r) @ np.asarray(T_cam_from_inertial, np.float64).T
    front = facing & (p_cam[:, 2] > 0)
    sl = np.full((len(o), 2), np.nan)
    if front.any():
        sl[front] = camera.project(p_cam[front])
    ok = front & np.all(np.isfinite(sl), 1)
    ok &= (sl[:, 0] >= -0.5 + margin_px) & (sl[:, 0] <= camera.width - 0.5 - margin_px)
    ok &= (sl[:, 1] >= -0.5 + margin_px) & (sl[:, 1] <= camera.height - 0.5 - margin_px)
    idx = np.nonzero(ok)[0]
    return sl[idx], idx


def _chamfer_search(pred: np.ndarray, obs: np.ndarray, shape: tuple[int, int], o: MatchOptions) -> np.ndarray:
    import cv2

    H, W = shape
    raster = np.ones((H, W), np.uint8)
    ij = np.round(obs).astype(int)
    inside = (ij[:, 0] >= 0) & (ij[:, 0] < W) & (ij[:, 1] >= 0) & (ij[:, 1] < H)
    raster[ij[inside, 1], ij[inside, 0]] = 0
    D = cv2.distanceTransform(raster, cv2.DIST_L2, cv2.DIST_MASK_PRECISE).astype(np.float64)
    def cost_of(ds, dl):
        ps = np.round(pred[:, 0])[None, :].astype(int) + ds[:, None]
        pl = np.round(pred[:, 1])[None, :].astype(int) + dl[:, None]
        inside = (ps >= 0) & (ps < W) & (pl >= 0) & (pl < H)
        c = np.where(inside, np.minimum(D[np.clip(pl, 0, H - 1), np.clip(ps, 0, W - 1)], o.chamfer_cap_px),
                     o.chamfer_cap_px)
        return c.mean(axis=1) + 1e-9 * (ds**2 + dl**2)   # ties → the smallest shift

    n = int(math.ceil(o.search_px))
    step = 2 if n > 8 else 1                               # coarse grid, then ±2 px at 1 px
    g = np.arange(-n, n + 1, step)
    ds, dl = (a.ravel() for a in np.meshgrid(g, g))
    c = cost_of(ds, dl)
    best = np.array([ds[np.argmin(c)], dl[np.argmin(c)]])
    f = np.arange(-2, 3)
    ds, dl = (a.ravel() + b for a, b in zip(np.meshgrid(f, f), best))
    c = cost_of(ds, dl)
    return np.array([ds[np.argmin(c)], dl[np.argmin(c)]], np.float64)


def _normals(obs: np.ndarray, tree, k: int = 6) -> np.ndarray:
    """Unit normals (n, 2) of the edge curve at each point: the minor axis of its k nearest neighbours."""
    _, nb = tree.query(obs, k=min(k, len(obs)))
    q = obs[nb] - obs[nb].mean(axis=1, keepdims=True)
    C = np.einsum("nki,nkj->nij", q, q)
    _, vec = np.linalg.eigh(C)
    return vec[:, :, 0]


def register_translation(pred: np.ndarray, obs: np.ndarray, shape: tuple[int, int],
                         options: MatchOptions = MatchOptions()) -> tuple[np.ndarray, np.ndarray, float]:
    """Shift δ (2,) with pred + δ ≈ obs: chamfer search then trimmed ICP. Returns (δ, inlier mask, median residual)."""
    from scipy.spatial import cKDTree

    o = options
    delta = _chamfer_search(pred, obs, shape, o)
    tree = cKDTree(obs)
    nrm = _normals(obs, tree)
    inl = np.zeros(len(pred), bool)
    med = np.inf
    for _ in range(o.icp_iterations):                     # point-to-line ICP, trimmed at the gate
        d, j = tree.query(pred + delta)
        inl = d <= o.gate_px
        if inl.sum() < 3:
            break
        n = nrm[j[inl]]
        res = np.einsum("ij,ij->i", n, obs[j[inl]] - (pred[inl] + delta))      # signed normal distances
        w = 1.0 / np.maximum(np.abs(res) / 0.5, 1.0)                           # Huber weights (0.5 px)
        A = (n * w[:, None]).T @ n
        if np.linalg.cond(A) > 1e6:                                            # straight coast: 1-D only
            step = np.median(obs[j[inl]] - (pred[inl] + delta), axis=0)
        else:
            step = np.linalg.solve(A, (n * (w * res)[:, None]).sum(0))
        delta = delta + step
        med = float(np.median(np.abs(res)))
        if np.hypot(*step) < 1e-4:
            break
    return delta, inl, med


def _spread(sl: np.ndarray, width: int, height: int, n_max: int) -> np.ndarray:
    """Indices of at most g² points, the one nearest each occupied cell centre of a g x g grid."""
    g = max(1, int(math.isqrt(n_max)))
    cu = np.clip((sl[:, 0] + 0.5) / width * g, 0, g - 1e-9).astype(int)
    cw = np.clip((sl[:, 1] + 0.5) / height * g, 0, g - 1e-9).astype(int)
    cell = cw * g + cu
    centre = np.stack([(cu + 0.5) / g * width - 0.5, (cw + 0.5) / g * height - 0.5], -1)
    d2 = np.sum((sl - centre) ** 2, 1)
    order = np.lexsort((d2, cell))
    return order[np.r_[True, cell[order][1:] != cell[order][:-1]]]


def match_coastline(obs_sl: np.ndarray, points_inertial: np.ndarray, r_prior: np.ndarray,
                    T_cam_from_inertial: np.ndarray, camera: CameraModel,
                    options: MatchOptions = MatchOptions()) -> Match:
    """Match extracted edge points ``obs_sl`` (n, 2) to database points (M, 3) seen from the a-priori state."""
    from scipy.spatial import cKDTree

    o = options
    pred, idx = project_database(points_inertial, r_prior, T_cam_from_inertial, camera)
    _, first = np.unique(np.round(pred).astype(np.int64) @ np.array([1, 1 << 20]), return_index=True)
    first = np.sort(first)                                 # one database point per pixel: even weights
    pred, idx = pred[first], idx[first]
    empty = Match(np.zeros(0, int), np.zeros((0, 2)), np.zeros((0, 2)), np.zeros((0, 3)), np.full(2, np.nan),
                  len(pred), 0, np.nan, False)
    obs = np.asarray(obs_sl, np.float64).reshape(-1, 2)
    if len(pred) < o.min_inliers or len(obs) < o.min_inliers:
        return empty
    delta, inl, med = register_translation(pred, obs, (camera.height, camera.width), o)
    if inl.sum() < o.min_inliers:
        empty.shift_px, empty.n_inliers = delta, int(inl.sum())
        return empty
    d, j = cKDTree(obs).query(pred + delta)
    good = np.nonzero(d <= o.gate_px)[0]
    pick = good[_spread(pred[good] + delta, camera.width, camera.height, o.points_per_image)]
    pick = pick[np.argsort(idx[pick])]
    # observed pixel: foot of the perpendicular from the registered prediction onto the local edge line
    # (normal part from the image, along-curve part from the registration, which a curve cannot give point-wise)
    n = _normals(obs, cKDTree(obs))[j[pick]]
    q = pred[pick] + delta
    obs_pick = q + n * np.einsum("ij,ij->i", n, obs[j[pick]] - q)[:, None]
    los = camera.unproject(obs_pick)
    los = los / np.linalg.norm(los, axis=1, keepdims=True)
    return Match(idx[pick], obs_pick, pred[pick], los, delta, len(pred), int(inl.sum()), med, True)
