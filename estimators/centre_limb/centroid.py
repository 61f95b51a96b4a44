"""Method (a): intensity centroid of the body's image, with a phase correction.

Description
-----------
1. Background ``b`` and its noise ``σ_b`` (median and 1.4826·MAD) from the pixels well outside the a-priori limb.
2. The blob: the connected region of ``I − b > max(threshold_frac·peak, 3σ_b)`` with the most signal inside a
   window around the a-priori limb, dilated by ``dilate_px``; weights ``w = I − b`` there (not clipped: zero-mean
   noise adds no bias).
3. Centre of brightness ``c_B = Σ w u / Σ w`` (8).
4. Phase correction: the brightness centroid of a sphere lies ``δ(α)·ρ`` toward the Sun's side of its disc centre
   (:mod:`.phase`, eqs. 5–7; α the a-priori phase angle, ``ρ`` the a-priori limb ellipse's radius along ``ê``, the
   image direction of the Sun across the line of sight):  ``c_D = c_B − δ(α) ρ ê`` (9).
5. Perspective: a uniform disc's centroid is the centre of the limb conic, not the projected body centre (they differ
   off-axis, :mod:`renderlab.geometry.conic`); the a-priori difference is added: ``c = c_D + (p̂ − ĉ_limb)`` (10).

With ``phase_correction = "none"`` and ``perspective = False`` it is the raw centre of brightness, the baseline.

Covariance: the noise term ``σ_b² Σ (u − c_B)(u − c_B)ᵀ / (Σ w)²`` (11) plus, along ``ê``, the model error
``(model_error_frac · δ ρ)²`` (12) (the law is not the body's; the correction is orthographic).

Tuning
------
=========================  ========  ==============================================================================
knob                       default   turn it when
=========================  ========  ==============================================================================
``phase_correction``       lambert   ``lommel_seeliger`` for dark, regolith-covered bodies; ``none``: the raw centroid
``threshold_frac``         0.05      raise when stray light or a second body enters the window
``dilate_px``              2         the faint terminator and limb pixels the threshold cuts (raise with blur)
``search_frac``            0.5       window margin around the a-priori limb, fraction of its radius (a-priori error)
``model_error_frac``       0.1       1σ of eq. 9 as a fraction of the correction
``min_radius_px``          1.0       smaller bodies are unresolved (a PSF centroid is another method)
=========================  ========  ==============================================================================

Use
---
::

    from estimators.centre_limb import IntensityCentroid, CentroidOptions
    est = IntensityCentroid(CentroidOptions(phase_correction="lambert")).measure(frame)
    est.centre_s, est.centre_l, est.cov_centre_px2, est.reason
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from estimators.centre_limb import common
from estimators.centre_limb.phase import offset


@dataclass(frozen=True)
class CentroidOptions:
    """Knobs of :class:`IntensityCentroid` (module docstring, Tuning)."""

    phase_correction: str = "lambert"
    perspective: bool = True
    threshold_frac: float = 0.05
    dilate_px: int = 2
    search_frac: float = 0.5
    model_error_frac: float = 0.1
    min_radius_px: float = 1.0


def _window(shape, pred, margin: float):
    u0, a, _, _ = pred.ellipse
    r = a + margin
    s0, s1 = max(int(math.floor(u0[0] - r)), 0), min(int(math.ceil(u0[0] + r)) + 1, shape[1])
    l0, l1 = max(int(math.floor(u0[1] - r)), 0), min(int(math.ceil(u0[1] + r)) + 1, shape[0])
    return l0, l1, s0, s1


def _blob(sub: np.ndarray, sigma: float, opts: CentroidOptions) -> np.ndarray | None:
    """Mask of the dilated brightest connected region of ``sub`` (background-subtracted), or None."""
    from scipy import ndimage

    peak = float(np.nanmax(sub)) if sub.size else 0.0
    thr = max(opts.threshold_frac * peak, 3.0 * sigma)
    if not peak > thr or not peak > 0:
        return None
    lab, n = ndimage.label(np.nan_to_num(sub, nan=0.0) > thr)
    if n == 0:
        return None
    flux = ndimage.sum_labels(np.nan_to_num(sub, nan=0.0), lab, index=np.arange(1, n + 1))
    mask = lab == 1 + int(np.argmax(flux))
    if opts.dilate_px > 0:
        mask = ndimage.binary_dilation(mask, iterations=int(opts.dilate_px))
    return mask & np.isfinite(sub)


class IntensityCentroid:
    """Centre of brightness with a phase correction (module docstring)."""

    name = "centroid_phase"

    def __init__(self, options: CentroidOptions = CentroidOptions()):
        if options.phase_correction not in ("lambert", "lommel_seeliger", "none"):
            raise ValueError(f"phase_correction must be lambert, lommel_seeliger or none, got "
                             f"{options.phase_correction!r}")
        self.options = options

    def measure(self, frame) -> common.Estimate:
        """Eqs. 8–12 on ``frame`` (attributes in :mod:`.common`)."""
        t0 = time.perf_counter()
        est = self._measure(frame)
        est.t_ms = (time.perf_counter() - t0) * 1e3
        return est

    def _measure(self, frame) -> common.Estimate:
        opts, cam = self.options, frame.camera
        pred = common.predict(frame)
        if common.off_image(cam, pred):
            return common.Estimate(reason=common.OFF_IMAGE)
        if pred.radius_px < opts.min_radius_px:
            return common.Estimate(reason=common.TOO_SMALL, diagnostics=f"radius {pred.radius_px:.2f} px")
        image = np.asarray(frame.image, float)
        margin = opts.search_frac * pred.ellipse[1] + 3.0
        bg, sigma = common.background(image, pred, margin + 2 * opts.dilate_px + 2)
        l0, l1, s0, s1 = _window(image.shape, pred, margin)
        sub = image[l0:l1, s0:s1] - bg
        mask = _blob(sub, sigma, opts)
        w = sub[mask] if mask is not None else np.zeros(0)
        if w.size == 0 or not np.sum(w) > 0:
            return common.Estimate(reason=common.UNLIT, diagnostics="no signal above the threshold")
        ll, ss = np.nonzero(mask)
        uv = np.column_stack([ss + s0, ll + l0]).astype(float)
        total = float(np.sum(w))
        cB = (w @ uv) / total  # eq. 8
        d = uv - cB
        cov = sigma**2 * (d.T @ d) / total**2  # eq. 11
        centre, shift = cB.copy(), np.zeros(2)
        if opts.phase_correction != "none":
            shift = self._phase_shift(cam, pred, opts.phase_correction)
            centre -= shift  # eq. 9
            e = shift / np.linalg.norm(shift) if np.linalg.norm(shift) > 0 else np.zeros(2)
            cov = cov + (opts.model_error_frac * np.linalg.norm(shift)) ** 2 * np.outer(e, e)  # eq. 12
        if opts.perspective:
            centre += pred.centre_sl - common.ideal_to_image(cam, pred.ellipse[0][None])[0]  # eq. 10
        return common.Estimate(centre_s=float(centre[0]), centre_l=float(centre[1]), cov_centre_px2=cov,
                               diagnostics=f"pixels {w.size}; phase shift {np.linalg.norm(shift):.3f} px",
                               extra={"brightness_centre": cB, "phase_shift": shift, "background": bg,
                                      "noise": sigma})

    @staticmethod
    def _phase_shift(cam, pred, law: str) -> np.ndarray:
        """``δ(α) ρ ê`` of eq. 9 in image pixels."""
        sp = pred.sun_perp()
        if np.linalg.norm(sp) < 1e-12:
            return np.zeros(2)
        J = cam.project_jacobian(pred.r_cam)
        e = J @ sp
        if not np.all(np.isfinite(e)) or np.linalg.norm(e) == 0:
            return np.zeros(2)
        e = e / np.linalg.norm(e)
        C = pred.conic / -(pred.conic[2, 2] + pred.conic[:2, 2] @ pred.ellipse[0])  # −1 at the centre → 1 on the limb
        rho = 1.0 / math.sqrt(float(e @ C[:2, :2] @ e))
        return offset(pred.phase_rad, law) * rho * e
