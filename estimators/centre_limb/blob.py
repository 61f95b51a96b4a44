"""Centre of a bright sphere in an image: an Otsu blob's centroid and an ellipse fitted to its outline.

Description
-----------
In a window about the predicted centre (half-width ⌈1.5 r + 4⌉ px, r the predicted apparent radius):

1. threshold t by Otsu's method (N. Otsu, "A threshold selection method from gray-level histograms", IEEE Trans.
   SMC 9(1), 1979, doi:10.1109/TSMC.1979.4310076) on an 8-bit rescale of the window; the largest 8-connected
   component above t; while it touches the window's edge (bright ground around the target), Otsu again on the
   bright class only (multi-level), up to 3 levels;
2. ``centroid``: the DN-weighted centroid of the component, weights DN − t (classic centre of brightness: biased
   toward the Sun at non-zero phase by the photocentre offset, :mod:`.phase`);
3. ``ellipse``: ``cv2.fitEllipse`` (least-squares conic) on the component's outer contour; its centre.

No result (reason): window off the image (``off_image``), no threshold or component (``no_detection``), the
component on the window's edge (``search_border``) or under 5 pixels, or a contour under 5 points
(``too_few_pixels``).

Tuning
------
None: the window scale (1.5 r + 4) and the 3 Otsu levels are fixed.

Use
---
``measure_sphere(dn, pred_sl, radius_px)`` → ``{"centroid": (s, l, score, reason, t_ms), "ellipse": ...}``; the
lab's study ``analytic_pointing`` scores both against the projected true centre.
"""

from __future__ import annotations

import math
import time

import numpy as np

METHODS = ("centroid", "ellipse")
OK, OFF_IMAGE, NO_DETECTION, SEARCH_BORDER, TOO_FEW_PIXELS = (
    "ok", "off_image", "no_detection", "search_border", "too_few_pixels")


def _otsu(values: np.ndarray) -> float | None:
    """Otsu threshold of a sample (OpenCV on an 8-bit rescale), in the sample's units."""
    import cv2

    lo, hi = float(values.min()), float(values.max())
    if hi - lo < 1.0:
        return None
    u8 = np.clip((values - lo) / (hi - lo) * 255.0, 0, 255).astype(np.uint8).reshape(-1, 1)
    t8, _ = cv2.threshold(u8, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    return lo + (t8 + 0.5) / 255.0 * (hi - lo)


def _segment(win: np.ndarray, levels: int = 3):
    """The brightest blob as (component mask, threshold in DN), or None.

    Otsu threshold, largest 8-connected component; while it touches the window's edge (bright ground
    around the target), threshold again inside the bright class (multi-level Otsu), up to ``levels``.
    """
    import cv2

    sample = win.ravel()
    best = None
    for _ in range(levels):
        thr = _otsu(sample)
        if thr is None:
            break
        n, labels, stats, _ = cv2.connectedComponentsWithStats((win > thr).astype(np.uint8), connectivity=8)
        if n < 2:
            break
        k = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
        best = (labels == k, thr)
        x, y, w, h = stats[k, :4]
        if x > 0 and y > 0 and x + w < win.shape[1] and y + h < win.shape[0]:
            break
        sample = sample[sample > thr]
        if sample.size < 10:
            break
    return best


def measure_sphere(dn: np.ndarray, pred_sl: np.ndarray, radius_px: float) -> dict[str, tuple]:
    """Both methods on the window of half-width ⌈1.5 r + 4⌉ px about ``pred_sl``: ``{method: (s, l, score, reason,
    t_ms)}`` (NaN s, l without a result; score: the blob's pixel count, or the fitted ellipse's axis ratio)."""
    import cv2

    h, w = dn.shape
    half = int(math.ceil(1.5 * radius_px + 4))
    c = np.rint(pred_sl).astype(int) if np.all(np.isfinite(pred_sl)) else np.array([-10**9, -10**9])
    s0, s1 = max(c[0] - half, 0), min(c[0] + half + 1, w)
    l0, l1 = max(c[1] - half, 0), min(c[1] + half + 1, h)
    out = {m: (math.nan, math.nan, math.nan, OFF_IMAGE, 0.0) for m in METHODS}
    if s1 - s0 < 5 or l1 - l0 < 5:
        return out
    t0 = time.perf_counter()
    win = dn[l0:l1, s0:s1].astype(np.float64)
    seg = _segment(win)
    t_seg = time.perf_counter() - t0
    if seg is None:
        return {m: (math.nan, math.nan, math.nan, NO_DETECTION, 1e3 * t_seg) for m in METHODS}
    mask, thr = seg
    ll, ss = np.nonzero(mask)
    edge = ll.min() == 0 or ss.min() == 0 or ll.max() == mask.shape[0] - 1 or ss.max() == mask.shape[1] - 1
    if edge or len(ll) < 5:
        why = SEARCH_BORDER if edge else TOO_FEW_PIXELS
        return {m: (math.nan, math.nan, math.nan, why, 1e3 * t_seg) for m in METHODS}
    t1 = time.perf_counter()
    wgt = win[ll, ss] - thr
    wgt = np.where(wgt > 0, wgt, 0.0) + 1e-12
    cs, cl = float(np.dot(wgt, ss) / wgt.sum()) + s0, float(np.dot(wgt, ll) / wgt.sum()) + l0
    out["centroid"] = (cs, cl, float(len(ll)), OK, 1e3 * (t_seg + time.perf_counter() - t1))
    t2 = time.perf_counter()
    contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    cont = max(contours, key=len)
    if len(cont) >= 5:
        (es, el), (a, b), _ = cv2.fitEllipse(cont)
        out["ellipse"] = (float(es) + s0, float(el) + l0, float(min(a, b) / max(a, b, 1e-12)), OK,
                          1e3 * (t_seg + time.perf_counter() - t2))
    else:
        out["ellipse"] = (math.nan, math.nan, math.nan, TOO_FEW_PIXELS, 1e3 * t_seg)
    return out
