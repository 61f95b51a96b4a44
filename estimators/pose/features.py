r"""Stage 1 image processing and the measurement database (Ivanov et al. 2018, §4, Fig. 4).

1. Noise filter: Gaussian blur (σ = ``blur_sigma_px``) of the DN image.
2. Binary image: threshold at ``bg + threshold_fraction·(peak − bg)`` (bg = image median, i.e. dark
   space); a global level fixed per frame, as the paper's "predetermined threshold".
3. Feature points: connected components of the binary image that look like isolated points (the
   paper's antenna tips), not edge segments: area in [``min_area_px``, ``max_area_px``] (bus and
   panels form large blobs and are dropped, 1-2 px specks are noise); elongation √(λ1/λ2) of the
   pixel second moments ≤ ``max_elongation`` (lit edges of the bus, panels and antenna shafts are
   thin lines); fill A / (4π√(λ1λ2)) ≥ ``min_fill`` (a filled ellipse has 1, ragged or hollow
   shapes less). Moments include the 1/12 px² of each pixel's own extent, so a single pixel is round.
   Centre = intensity-weighted centroid of the *unblurred* image over the component ("centre of
   illumination"). :func:`detect_blobs` returns every component with its shape numbers and the reason
   it was rejected, :func:`detect_points` the accepted centroids.
4. Tracking by ε-neighbourhood: a track continues with the nearest unclaimed detection within ε of
   its last position; no detection within ε ends it ("shadowed or unstable luminosity"); unclaimed
   detections start new tracks.
5. Database: tracks shorter than ``min_track_frames`` are dropped (the paper keeps the lengthiest
   records).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class DetectOptions:
    blur_sigma_px: float = 0.8
    threshold_fraction: float = 0.45
    min_area_px: int = 3
    max_area_px: int = 400
    max_elongation: float = 2.5
    min_fill: float = 0.6


@dataclass(frozen=True)
class TrackOptions:
    epsilon_px: float = 12.0
    min_track_frames: int = 5


@dataclass
class Track:
    """One feature track: frame indices and measured (s, l), in order."""

    track_id: int
    frames: list[int] = field(default_factory=list)
    sl: list[tuple[float, float]] = field(default_factory=list)
    ended: str = ""  # "", "lost" (no detection within ε), "end" (sequence ended)


@dataclass
class Blobs:
    """Connected components of one binary image: centroid (s, l), shape numbers and the gate verdict."""

    sl: np.ndarray           # (K, 2) intensity-weighted centroids
    area: np.ndarray         # (K,) pixels
    elongation: np.ndarray   # (K,) √(λ1/λ2)
    fill: np.ndarray         # (K,) A / (4π√(λ1λ2))
    reason: list[str]        # "" accepted, else "area", "elongation" or "fill"

    @property
    def accepted(self) -> np.ndarray:
        return np.array([r == "" for r in self.reason], bool)


def detect_blobs(dn: np.ndarray, opts: DetectOptions = DetectOptions()) -> Blobs:
    """All bright connected components of one image, with their shape and the point-like gate (steps 1-3)."""
    import cv2

    img = np.asarray(dn, np.float32)
    bg = float(np.median(img))
    sm = cv2.GaussianBlur(img, (0, 0), opts.blur_sigma_px) if opts.blur_sigma_px > 0 else img
    peak = float(sm.max())
    empty = Blobs(np.zeros((0, 2)), np.zeros(0), np.zeros(0), np.zeros(0), [])
    if peak <= bg:
        return empty
    binary = (sm > bg + opts.threshold_fraction * (peak - bg)).astype(np.uint8)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(binary, connectivity=8)
    w = np.clip(img - bg, 0, None)
    sl, area, elong, fill, reason = [], [], [], [], []
    for k in range(1, n):
        x0, y0, bw, bh, a = stats[k]
        lab = labels[y0:y0 + bh, x0:x0 + bw] == k
        ys, xs = np.nonzero(lab)
        wk = w[y0 + ys, x0 + xs]
        if wk.sum() <= 0:
            continue
        c = np.cov(np.vstack([xs, ys]), bias=True) if a > 1 else np.zeros((2, 2))
        lam = np.linalg.eigvalsh(c + np.eye(2) / 12.0)
        e = float(np.sqrt(lam[1] / lam[0]))
        f = float(a / (4 * np.pi * np.sqrt(lam[0] * lam[1])))
        why = ("area" if not opts.min_area_px <= a <= opts.max_area_px else
               "elongation" if e > opts.max_elongation else "fill" if f < opts.min_fill else "")
        sl.append((float(x0 + xs @ wk / wk.sum()), float(y0 + ys @ wk / wk.sum())))
        area.append(a), elong.append(e), fill.append(f), reason.append(why)
    if not sl:
        return empty
    return Blobs(np.array(sl), np.array(area, float), np.array(elong), np.array(fill), reason)


def detect_points(dn: np.ndarray, opts: DetectOptions = DetectOptions()) -> np.ndarray:
    """Centroids (K, 2) as (s, l) of the point-like bright blobs in one image (pixel-centre convention)."""
    b = detect_blobs(dn, opts)
    return b.sl[b.accepted].reshape(-1, 2)


def track_points(detections: list[np.ndarray], opts: TrackOptions = TrackOptions(),
                 frame_ids: list[int] | None = None) -> list[Track]:
    """ε-neighbourhood association of per-frame detections into tracks (all tracks, short ones too)."""
    frame_ids = list(range(len(detections))) if frame_ids is None else list(frame_ids)
    tracks: list[Track] = []
    active: list[Track] = []
    for f, det in zip(frame_ids, detections):
        det = np.asarray(det, float).reshape(-1, 2)
        claimed = np.zeros(len(det), bool)
        pairs = []
        for t in active:
            if len(det):
                dist = np.hypot(*(det - np.asarray(t.sl[-1])).T)
                for j in np.nonzero(dist <= opts.epsilon_px)[0]:
                    pairs.append((dist[j], t.track_id, j))
        pairs.sort()
        taken = set()
        by_id = {t.track_id: t for t in active}
        for _, tid, j in pairs:
            if tid in taken or claimed[j]:
                continue
            by_id[tid].frames.append(f)
            by_id[tid].sl.append(tuple(det[j]))
            taken.add(tid)
            claimed[j] = True
        still = []
        for t in active:
            if t.track_id in taken:
                still.append(t)
            else:
                t.ended = "lost"
        for j in np.nonzero(~claimed)[0]:
            t = Track(len(tracks), [f], [tuple(det[j])])
            tracks.append(t)
            still.append(t)
        active = still
    for t in active:
        t.ended = "end"
    return tracks


@dataclass
class MeasurementDatabase:
    """The filtered database: one row per (track, frame) measurement."""

    track_ids: np.ndarray   # (K,) distinct kept tracks
    frame: np.ndarray       # (N,) frame index of each measurement
    point: np.ndarray       # (N,) index into track_ids
    sl: np.ndarray          # (N, 2)
    dropped_tracks: int = 0

    @property
    def n_points(self) -> int:
        return len(self.track_ids)


def build_database(tracks: list[Track], opts: TrackOptions = TrackOptions()) -> MeasurementDatabase:
    """Keep tracks with at least ``min_track_frames`` measurements."""
    keep = [t for t in tracks if len(t.frames) >= opts.min_track_frames]
    frame, point, sl = [], [], []
    for k, t in enumerate(keep):
        frame += t.frames
        point += [k] * len(t.frames)
        sl += t.sl
    return MeasurementDatabase(np.array([t.track_id for t in keep], int), np.array(frame, int),
                               np.array(point, int), np.array(sl, float).reshape(-1, 2),
                               dropped_tracks=len(tracks) - len(keep))
