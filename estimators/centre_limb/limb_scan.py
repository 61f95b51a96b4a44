"""Sub-pixel points of the lit limb, scanned along rays from the a-priori limb centre (methods (b) and (c)).

Description
-----------
Rays leave the a-priori limb-conic centre ``u₀`` (ideal pixels) at ``n_rays`` angles. Along ray ``d`` the a-priori limb
is at ``t* = √(−f₀ / dᵀQd)`` (the conic ``(u − u₀)ᵀQ(u − u₀) = −f₀``). A ray is kept only where the limb is lit: its
a-priori tangency point ``p = (xᵀA r / xᵀA x)·x`` on the ray ``x`` has the normal ``n ∝ A(p − r)`` with

    n̂ · ŝ > sin(terminator_margin) · |ŝ_⊥|                                                                  (13)

(ŝ the Sun, ŝ_⊥ its part across the line of sight: at full phase every limb point passes, at phase α the rays within
``terminator_margin`` of the cusps are dropped, and the terminator itself, n̂·ŝ = 0 on the dark side of the disc,
never enters). The image is sampled along the ray every ``step_px`` over ``t* ± search_px`` (bilinear, through the
camera's distortion). The edge is where the profile falls most steeply (the Gaussian-smoothed derivative, σ =
``smooth_px``); it is refined to where the profile crosses the mid-line between straight lines fitted to the inside
and the outside of the edge (14) — for a blurred step with linear sides that crossing is off the step by
``(g_out − g_in)·m₁/Δ`` only (m₁ the half-moment of the blur kernel, g the side slopes, Δ the step). A step smaller
than ``min_contrast_frac`` of the image's peak or ``min_contrast_sigma`` times the background noise is dropped.
The limb point is ``u₀ + t d`` (ideal pixels; the image pixels through the distortion are returned too).

Tuning
------
========================  ==========  =============================================================================
knob                      default     turn it when
========================  ==========  =============================================================================
``n_rays``                0 (auto)    rays over the full circle; auto: one per 1.5 px of limb, 32 … 720
``search_px``             0 (auto)    half-length of the scan about the a-priori limb; auto: max(4, 0.2 ρ) px
``terminator_margin_deg`` 15          angle kept from the cusps (limb/terminator corners), eq. 13
``smooth_px``             0.7         σ of the edge detector; raise with blur or noise
``min_contrast_frac``     0.05        weakest step kept, fraction of the image peak above background
``min_contrast_sigma``    5           weakest step kept, in background σ
========================  ==========  =============================================================================

Use
---
::

    from estimators.centre_limb.common import predict
    from estimators.centre_limb.limb_scan import LimbScanOptions, limb_points
    pred, pts, failed = limb_points(frame, LimbScanOptions(), min_radius_px=4, min_points=8)
    pts.ideal, pts.image      # (n, 2) limb points, ideal and image pixels (failed: an Estimate with the reason)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from estimators.centre_limb import common


@dataclass(frozen=True)
class LimbScanOptions:
    """Knobs of :func:`scan_limb` (module docstring, Tuning)."""

    n_rays: int = 0
    search_px: float = 0.0
    step_px: float = 0.2
    terminator_margin_deg: float = 15.0
    smooth_px: float = 0.7
    min_contrast_frac: float = 0.05
    min_contrast_sigma: float = 5.0


@dataclass
class LimbPoints:
    """Limb points of one image: ideal pixels (n, 2), image pixels (n, 2), and counts for the diagnostics."""

    ideal: np.ndarray
    image: np.ndarray
    n_rays: int
    n_lit: int


def _lit(pred, u: np.ndarray, margin_deg: float) -> np.ndarray:
    """Eq. 13 for a-priori limb points ``u`` (n, 2) in ideal pixels."""
    A = pred.U.T @ pred.U
    x = np.linalg.solve(pred.K, np.column_stack([u, np.ones(len(u))]).T).T
    t = (x @ A @ pred.r_cam) / np.einsum("ij,jk,ik->i", x, A, x)
    n = (t[:, None] * x - pred.r_cam) @ A
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return n @ pred.sun_cam > math.sin(math.radians(margin_deg)) * np.linalg.norm(pred.sun_perp())


def _edge(prof: np.ndarray, step: float, opts: LimbScanOptions, min_step: float) -> float | None:
    """Eq. 14: the sub-pixel position (in samples) of the outward bright→dark edge of ``prof``, or None."""
    from scipy.ndimage import gaussian_filter1d

    g = gaussian_filter1d(prof, opts.smooth_px / step, order=1)
    k = int(np.argmin(g))
    near, far = int(round(1.5 / step)), int(round(3.5 / step))
    if k - far < 0 or k + far >= len(prof):
        return None
    i_in, i_out = np.arange(k - far, k - near + 1), np.arange(k + near, k + far + 1)
    p_in, p_out = np.polyfit(i_in, prof[i_in], 1), np.polyfit(i_out, prof[i_out], 1)
    if not np.polyval(p_in, k) - np.polyval(p_out, k) > min_step:
        return None
    i = np.arange(k - near, k + near + 1)
    f = prof[i] - 0.5 * (np.polyval(p_in, i) + np.polyval(p_out, i))
    cross = np.nonzero((f[:-1] > 0) & (f[1:] <= 0))[0]
    if len(cross) == 0:
        return None
    j = cross[np.argmin(np.abs(cross - near))]
    return float(i[j] + f[j] / (f[j] - f[j + 1]))


def _profiles(image, valid, cam, pts: np.ndarray):
    """Bilinear samples of ``image`` at ideal-pixel points (rays, samples, 2); NaN off the image or at invalid pixels."""
    from scipy.ndimage import map_coordinates

    sl = common.ideal_to_image(cam, pts.reshape(-1, 2))
    H, W = image.shape
    ok = (np.all(np.isfinite(sl), axis=1) & (sl[:, 0] >= 0) & (sl[:, 0] <= W - 1) & (sl[:, 1] >= 0)
          & (sl[:, 1] <= H - 1))
    coords = np.where(ok[:, None], sl, 0.0)[:, ::-1].T
    vals = map_coordinates(image, coords, order=1, mode="nearest")
    if valid is not None:
        good = map_coordinates(np.asarray(valid, float), coords, order=1, mode="nearest") > 0.999
        ok &= good
    return np.where(ok, vals, np.nan).reshape(pts.shape[:2])


def scan_limb(frame, pred, opts: LimbScanOptions, background: float, noise_sigma: float) -> LimbPoints:
    """The lit limb's points in ``frame.image`` around the a-priori :class:`~.common.Prediction` (module docstring);
    ``background`` and ``noise_sigma`` (its robust σ) set the contrast floor."""
    cam = frame.camera
    image = np.asarray(frame.image, float)
    u0, a, b, _ = pred.ellipse
    rho = math.sqrt(a * b)
    n_rays = opts.n_rays or int(np.clip(round(2 * math.pi * rho / 1.5), 32, 720))
    search = min(opts.search_px or max(4.0, 0.2 * rho), 0.8 * b)
    phi = 2 * math.pi * np.arange(n_rays) / n_rays
    d = np.column_stack([np.cos(phi), np.sin(phi)])
    Cn = pred.conic / -(pred.conic[2, 2] + pred.conic[:2, 2] @ u0)
    t_star = 1.0 / np.sqrt(np.einsum("ij,jk,ik->i", d, Cn[:2, :2], d))
    lit = _lit(pred, u0 + t_star[:, None] * d, opts.terminator_margin_deg)
    if not np.any(lit):
        return LimbPoints(np.zeros((0, 2)), np.zeros((0, 2)), n_rays, 0)
    d, t_star = d[lit], t_star[lit]
    offs = np.arange(-search, search + opts.step_px / 2, opts.step_px)
    t = t_star[:, None] + offs[None, :]
    prof = _profiles(image, frame.valid, cam, u0 + t[..., None] * d[:, None, :])
    finite = image[np.isfinite(image)]
    peak = float(finite.max()) if finite.size else 0.0
    min_step = max(opts.min_contrast_frac * (peak - background), opts.min_contrast_sigma * noise_sigma)
    out = []
    for k in range(len(d)):
        if not np.all(np.isfinite(prof[k])):
            continue
        e = _edge(prof[k], opts.step_px, opts, min_step)
        if e is not None:
            out.append(u0 + (t_star[k] + offs[0] + e * opts.step_px) * d[k])
    ideal = np.array(out).reshape(-1, 2)
    return LimbPoints(ideal, common.ideal_to_image(cam, ideal) if len(ideal) else ideal, n_rays, int(lit.sum()))


def limb_points(frame, opts: LimbScanOptions, min_radius_px: float, min_points: int):
    """(prediction, :class:`LimbPoints`, None) or (prediction, None, an Estimate with the reason there is none)."""
    pred = common.predict(frame)
    if common.off_image(frame.camera, pred):
        return pred, None, common.Estimate(reason=common.OFF_IMAGE)
    if pred.radius_px < min_radius_px:
        return pred, None, common.Estimate(reason=common.TOO_SMALL, diagnostics=f"radius {pred.radius_px:.2f} px")
    margin = (opts.search_px or max(4.0, 0.2 * pred.radius_px)) + 4.0
    bg, sigma = common.background(np.asarray(frame.image, float), pred, margin)
    pts = scan_limb(frame, pred, opts, bg, sigma)
    diag = f"rays {pts.n_rays}, lit {pts.n_lit}, edges {len(pts.ideal)}"
    image = np.asarray(frame.image, float)
    signal = float(np.nanmax(image)) - bg if np.any(np.isfinite(image)) else 0.0
    if pts.n_lit == 0 or (len(pts.ideal) == 0 and not signal > opts.min_contrast_sigma * sigma):
        return pred, None, common.Estimate(reason=common.UNLIT, diagnostics=diag)
    if len(pts.ideal) < min_points:
        return pred, None, common.Estimate(reason=common.TOO_FEW_POINTS, diagnostics=diag,
                                           limb_points=pts.image)
    return pred, pts, None
