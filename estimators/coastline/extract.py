r"""Coastline extraction from a nadir sensor image: segmentation, morphology, sub-pixel land/water edges.

The paper (Straub & Christian, Section II.A, refs 3 and 11) identifies coastline pixels by segmenting the
image into land and water and tracing the boundary; it then assumes those pixels perfectly identified. This
module does the image part, onboard-style (numpy + OpenCV only):

1. **Illumination flattening.** Over a LEO frame (≈500 km) the Lambertian factor cos i varies smoothly, so the
   log image is ``log I = log A(class) + t(s, l)`` with a smooth trend t. The classes and a quadratic trend
   are fitted alternately (least squares with one offset per class); the flattened image is ``I / exp(t)``.
2. **Segmentation.** Otsu's three-class split of the flattened log image is accepted as water / land / cloud
   when cloud is ≥ ``cloud_ratio`` x land and land ≥ ``min_land_water_ratio`` x water (clouds, albedo ≈
   0.5-0.8, are several times brighter than land, ≈ 0.1-0.3, itself several times brighter than water,
   ≈ 0.05) and the middle class is a surface (≥ ``min_class_fraction`` of the image, ≥ 30 % of it surviving a
   3 x 3 erosion — not just the mixed pixels along water/cloud edges); otherwise the two-class Otsu threshold
   separates water from land.
3. **Morphology.** Land and water components smaller than ``min_region_px`` are absorbed by their
   surroundings (islets, lakes and noise below the resolution are not matchable coastline).
4. **Edges.** Between every pair of 4-neighbour pixels labelled water | land, the sub-pixel crossing of the
   flattened *linear* image at the mid-level ``(A_water + A_land)/2`` is the edge point (the pixel integrates
   radiance linearly, so the half-way level marks where the true boundary crosses).
5. **Clouds.** Edges between cloud and anything are cloud edges: rejected (counted). Land/water edges within
   ``cloud_margin_px`` of a cloud pixel may be cloud shadows or cloud-cut coast and cannot be decided from
   brightness: they are kept with :data:`FLAG_NEAR_CLOUD`. A frame whose two classes differ by more than any
   land/water contrast (``max_land_water_ratio``) may be water vs cloud with no land at all: every edge gets
   :data:`FLAG_UNDECIDED`.

Pixel convention: (s, l) = (column, row), the centre of the top-left pixel is (0, 0).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["ExtractOptions", "Extraction", "extract_coastline", "otsu_threshold", "FLAG_NEAR_CLOUD",
           "FLAG_UNDECIDED", "WATER", "LAND", "CLOUD", "INVALID"]

FLAG_NEAR_CLOUD = 1   #: land/water edge next to a cloud (may be a cloud shadow edge)
FLAG_UNDECIDED = 2    #: classes too far apart for land/water: maybe water/cloud with no land
WATER, LAND, CLOUD, INVALID = 0, 1, 2, 255


@dataclass(frozen=True)
class ExtractOptions:
    """Extraction settings (dimensionless ratios are of flattened radiance levels)."""

    min_region_px: int = 6              # smaller land/water components are absorbed (morphology)
    cloud_ratio: float = 1.8            # third (bright) class ≥ this x the land level → cloud
    min_land_water_ratio: float = 1.8   # ... and land ≥ this x water (else two classes)
    min_class_fraction: float = 0.02    # ... and land covers ≥ this share, ≥ 30 % of it away from edges
    max_land_water_ratio: float = 8.0   # two classes further apart than this: possibly water vs cloud
    cloud_margin_px: int = 2            # land/water edges this close to cloud are flagged
    dark_floor: float = 1.0             # pixels at or below are invalid (night side, space, dead pixels)
    border_px: int = 1                  # edges touching the image border are dropped
    trend_iterations: int = 3


@dataclass
class Extraction:
    """Edge points (n, 2) as (s, l), their flags (n,), the label image and the class levels."""

    points: np.ndarray
    flags: np.ndarray
    labels: np.ndarray
    level_water: float
    level_land: float
    level_cloud: float | None
    n_cloud_edges: int
    flattened: np.ndarray

    @property
    def clean(self) -> np.ndarray:
        """Mask of edge points without flags."""
        return self.flags == 0


def otsu_threshold(values: np.ndarray, bins: int = 256) -> float:
    """Otsu's threshold (max between-class variance) of a 1-D sample."""
    v = np.asarray(values, np.float64).ravel()
    v = v[np.isfinite(v)]
    if v.size < 2 or v.max() <= v.min():
        return float(v.mean()) if v.size else 0.0
    hist, edges = np.histogram(v, bins=bins)
    centres = 0.5 * (edges[1:] + edges[:-1])
    w0 = np.cumsum(hist)
    w1 = w0[-1] - w0
    m0 = np.cumsum(hist * centres)
    mt = m0[-1]
    with np.errstate(invalid="ignore", divide="ignore"):
        between = (mt * w0 / w0[-1] - m0) ** 2 / (w0 * w1)
    between[~np.isfinite(between)] = -1.0
    return float(edges[int(np.argmax(between)) + 1])


def _design(shape) -> np.ndarray:
    H, W = shape
    l, s = np.mgrid[0:H, 0:W]
    x, y = (s - 0.5 * (W - 1)) / W, (l - 0.5 * (H - 1)) / H
    return np.stack([x, y, x * x, x * y, y * y], -1).reshape(-1, 5)


def otsu_two_thresholds(values: np.ndarray, bins: int = 128) -> tuple[float, float]:
    """Two-threshold (three-class) Otsu: the pair maximising Σ w_k μ_k² over the histogram."""
    v = np.asarray(values, np.float64).ravel()
    v = v[np.isfinite(v)]
    hist, edges = np.histogram(v, bins=bins)
    c = 0.5 * (edges[1:] + edges[:-1])
    W = np.concatenate([[0.0], np.cumsum(hist)])
    M = np.concatenate([[0.0], np.cumsum(hist * c)])
    i, j = np.triu_indices(bins + 1, k=1)                # classes [0, i), [i, j), [j, bins)
    ok = (i > 0) & (j < bins)
    i, j = i[ok], j[ok]
    w = np.stack([W[i], W[j] - W[i], W[-1] - W[j]])
    m = np.stack([M[i], M[j] - M[i], M[-1] - M[j]])
    with np.errstate(invalid="ignore", divide="ignore"):
        score = np.where(np.all(w > 0, 0), np.sum(m * m / w, 0), -np.inf)
    k = int(np.argmax(score))
    return float(edges[i[k]]), float(edges[j[k]])


def _classify(logf: np.ndarray, valid: np.ndarray, o: ExtractOptions):
    """Labels of a flattened log image: three classes (water, land, cloud) when Otsu's three-class split has
    both steps ≥ the land/water and cloud/land ratios, else two (water, land)."""
    lab = np.full(logf.shape, INVALID, np.uint8)
    x = logf[valid]
    t1, t2 = otsu_two_thresholds(x)
    lo, mid, hi = x[x < t1], x[(x >= t1) & (x < t2)], x[x >= t2]
    three = (min(lo.size, mid.size, hi.size) > 10 and np.median(hi) - np.median(mid) > np.log(o.cloud_ratio)
             and np.median(mid) - np.median(lo) > np.log(o.min_land_water_ratio))
    if three:   # the middle class must be a surface, not the mixed pixels along water/cloud or water/land edges
        import cv2

        mid_mask = (valid & (logf >= t1) & (logf < t2)).astype(np.uint8)
        interior = cv2.erode(mid_mask, np.ones((3, 3), np.uint8)).sum()
        three = mid_mask.sum() >= o.min_class_fraction * x.size and interior >= 0.3 * mid_mask.sum()
    if three:
        lab[valid & (logf < t1)] = WATER
        lab[valid & (logf >= t1) & (logf < t2)] = LAND
        lab[valid & (logf >= t2)] = CLOUD
        return lab
    t = otsu_threshold(x)
    lab[valid & (logf < t)] = WATER
    lab[valid & (logf >= t)] = LAND
    return lab


def _absorb_small(lab: np.ndarray, cls: int, other: int, min_px: int) -> None:
    import cv2

    n, comp, stats, _ = cv2.connectedComponentsWithStats((lab == cls).astype(np.uint8), connectivity=4)
    small = np.nonzero(stats[1:, cv2.CC_STAT_AREA] < min_px)[0] + 1
    if small.size:
        lab[np.isin(comp, small)] = other


def extract_coastline(image: np.ndarray, options: ExtractOptions = ExtractOptions()) -> Extraction:
    """Coastline edge points of one sensor image (DN or radiance, (H, W)); see the module docstring."""
    import cv2

    o = options
    img = np.asarray(image, np.float64)
    if img.ndim != 2:
        raise ValueError(f"extract_coastline expects a 2-D image, got shape {img.shape}")
    valid = np.isfinite(img) & (img > o.dark_floor)
    if valid.sum() < 16:
        raise ValueError("extract_coastline: fewer than 16 valid (lit) pixels")
    logi = np.log(np.where(valid, img, 1.0))
    A = _design(img.shape)
    trend = np.zeros(img.size)
    for _ in range(o.trend_iterations):
        logf = logi - trend.reshape(img.shape)
        lab = _classify(logf, valid, o)
        use = (lab != INVALID).ravel()
        classes = [c for c in (WATER, LAND, CLOUD) if np.any(lab.ravel()[use] == c)]
        onehot = np.stack([(lab.ravel() == c) for c in classes], -1).astype(np.float64)
        X = np.concatenate([A, onehot], -1)[use]
        coef, *_ = np.linalg.lstsq(X, logi.ravel()[use], rcond=None)
        trend = A @ coef[:5]
    logf = logi - trend.reshape(img.shape)
    lab = _classify(logf, valid, o)
    # morphology: tiny land in water and tiny water in land are not matchable coastline
    _absorb_small(lab, LAND, WATER, o.min_region_px)
    _absorb_small(lab, WATER, LAND, o.min_region_px)
    flat = np.where(valid, np.exp(logf), np.nan)
    lev_w = float(np.median(flat[lab == WATER])) if np.any(lab == WATER) else np.nan
    lev_l = float(np.median(flat[lab == LAND])) if np.any(lab == LAND) else np.nan
    lev_c = float(np.median(flat[lab == CLOUD])) if np.any(lab == CLOUD) else None
    thr = 0.5 * (lev_w + lev_l)
    near_cloud = np.zeros(lab.shape, bool)
    if np.any(lab == CLOUD):
        k = 2 * o.cloud_margin_px + 1
        near_cloud = cv2.dilate((lab == CLOUD).astype(np.uint8), np.ones((k, k), np.uint8)) > 0
    undecided = bool(np.isfinite(lev_w) and np.isfinite(lev_l) and lev_l / lev_w > o.max_land_water_ratio)
    H, W = lab.shape
    pts, flags, n_cloud_edges = [], [], 0
    for axis in (0, 1):
        a_lab = lab[:-1, :] if axis == 0 else lab[:, :-1]
        b_lab = lab[1:, :] if axis == 0 else lab[:, 1:]
        a_v = flat[:-1, :] if axis == 0 else flat[:, :-1]
        b_v = flat[1:, :] if axis == 0 else flat[:, 1:]
        pair = np.minimum(a_lab, b_lab), np.maximum(a_lab, b_lab)
        n_cloud_edges += int(np.sum((pair[1] == CLOUD) & (pair[0] != CLOUD)))
        edge = (pair[0] == WATER) & (pair[1] == LAND)
        r, c = np.nonzero(edge)
        va, vb = a_v[edge], b_v[edge]
        with np.errstate(invalid="ignore", divide="ignore"):
            f = np.clip((thr - va) / (vb - va), 0.0, 1.0)
        f = np.where(np.isfinite(f), f, 0.5)
        s = c + (f if axis == 1 else 0.0)
        ln = r + (f if axis == 0 else 0.0)
        fl = np.zeros(len(r), np.int32)
        nc = near_cloud[r, c] | (near_cloud[r + 1, c] if axis == 0 else near_cloud[r, c + 1])
        fl[nc] |= FLAG_NEAR_CLOUD
        if undecided:
            fl |= FLAG_UNDECIDED
        pts.append(np.stack([s, ln], -1))
        flags.append(fl)
    P = np.concatenate(pts) if pts else np.zeros((0, 2))
    F = np.concatenate(flags) if flags else np.zeros(0, np.int32)
    b = o.border_px
    keep = (P[:, 0] >= b) & (P[:, 0] <= W - 1 - b) & (P[:, 1] >= b) & (P[:, 1] <= H - 1 - b)
    return Extraction(P[keep], F[keep], lab, lev_w, lev_l, lev_c, n_cloud_edges, flat)
