"""Two bright-spot methods: the brightest pixel, and a background-subtracted centroid in a window around it."""

from __future__ import annotations

import math

import numpy as np

from renderlab_toy_kind.kind import SpotFrame, SpotReason, SpotResult


def _peak(frame: SpotFrame, n_sigma: float, half: int):
    """(row, col, background, threshold) of the brightest pixel, or a reason."""
    img = frame.image
    background = float(np.median(img))
    r, c = np.unravel_index(int(np.argmax(img)), img.shape)
    if img[r, c] - background < n_sigma * max(frame.noise_dn, 1e-12):
        return None, SpotReason.NO_SPOT.value
    if not (half <= r < img.shape[0] - half and half <= c < img.shape[1] - half):
        return None, SpotReason.AT_BORDER.value
    return (int(r), int(c), background), SpotReason.OK.value


class PeakPixel:
    """The brightest pixel (whole-pixel position; claimed σ = 1/√12 px, the rounding's)."""

    name = "peak_pixel"

    def __init__(self, n_sigma: float = 8.0):
        self.n_sigma = n_sigma

    def locate(self, frame: SpotFrame) -> SpotResult:
        peak, reason = _peak(frame, self.n_sigma, 0)
        if peak is None:
            return SpotResult(reason=reason)
        return SpotResult(spot_s=float(peak[1]), spot_l=float(peak[0]), sigma_px=1 / math.sqrt(12))


class WindowCentroid:
    """Centroid of (image − median) in a (2h+1)² window around the brightest pixel; claimed σ from the background
    noise propagated through the centroid (first order)."""

    name = "window_centroid"

    def __init__(self, n_sigma: float = 8.0, half: int = 4):
        self.n_sigma, self.half = n_sigma, half

    def locate(self, frame: SpotFrame) -> SpotResult:
        peak, reason = _peak(frame, self.n_sigma, self.half)
        if peak is None:
            return SpotResult(reason=reason)
        r, c, background = peak
        h = self.half
        win = frame.image[r - h:r + h + 1, c - h:c + h + 1] - background
        total = float(win.sum())
        off = np.arange(-h, h + 1, dtype=float)
        ds, dl = float(win.sum(axis=0) @ off) / total, float(win.sum(axis=1) @ off) / total
        sigma = frame.noise_dn * math.sqrt(float(np.sum(off ** 2)) * (2 * h + 1)) / total
        return SpotResult(spot_s=c + ds, spot_l=r + dl, sigma_px=max(sigma, 1e-3))
