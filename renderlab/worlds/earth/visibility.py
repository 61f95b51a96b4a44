r"""Coastline visibility (Straub & Christian Fig. 4): the share of images that contain coastline.

For a circular orbit (two-body, eqs. 10-12) images are taken every ``cadence_s`` for ``hours``; the camera
points at nadir (:func:`renderlab.dynamics.orbits.nadir_attitude`). Each image's exact footprint is the
loop where its boundary rays meet the WGS-84 ellipsoid (the paper's eq. 1 gives its flat-Earth size); an
image *contains coastline* when that polygon intersects the full-resolution GSHHG coastline (STRtree
query, one vectorised GEOS call per footprint batch). Options: *daylight* keeps only coast points with the
sun above ``min_sun_elevation_deg`` (real sun for the epoch); *clouds* hides coast points under a seeded
:class:`~renderlab.worlds.earth.clouds.CloudField` with the given cover fraction. An image then counts when
at least one coast point inside it is lit and clear.

Speed: the sun's elevation over a footprint (far smaller than a hemisphere) is extreme on its boundary
(sin of the elevation is linear in position on a sphere; the geodetic normal differs by < 0.2°), so an
image whose boundary is lit everywhere by more than :data:`SUN_MARGIN_DEG` is lit inside, and one dark
everywhere is dark: only images across the terminator need the per-point test. Cloud tests use every
:data:`CLOUD_THIN`-th coast vertex (≈ 1 km apart; the cloud field is smooth at ≥ 20 km).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from renderlab.dynamics.orbits import OrbitElements, nadir_attitude
from renderlab.worlds.earth import footprint, wgs84
from renderlab.worlds.earth.clouds import CloudField
from renderlab.worlds.earth.sun import sun_eci

CLOUD_THIN = 8
SUN_MARGIN_DEG = 0.5


@dataclass(frozen=True)
class VisibilityOptions:
    altitude_m: float = 1000e3
    hours: float = 24.0
    cadence_s: float = 30.0
    epoch_utc: str = "2024-03-20T00:00:00Z"
    raan_deg: float = 0.0
    u0_deg: float = 0.0
    daylight_only: bool = False
    min_sun_elevation_deg: float = 0.0
    cloud_cover: float = 0.0
    seed: int = 0
    n_per_edge: int = 8


def nadir_track(incl_deg: float, opt: VisibilityOptions):
    """ECEF positions (N, 3), R_ecef_from_cam (N, 3, 3), times (N,) and Julian dates of a nadir camera."""
    t = np.arange(0.0, opt.hours * 3600.0 - 1e-9, opt.cadence_s)
    el = OrbitElements.circular(opt.altitude_m, incl_deg, opt.raan_deg, opt.u0_deg)
    r, v = el.state(t)
    jd = wgs84.julian_date(wgs84.parse_epoch(opt.epoch_utc), t)
    R_ef = wgs84.R_ecef_from_eci(jd)
    pos = np.einsum("nij,nj->ni", R_ef, r)
    R_cam = R_ef @ nadir_attitude(r, v)
    return pos, R_cam, t, jd


def coast_in_images(polys: np.ndarray, gshhg) -> np.ndarray:
    """Bool (N,): which footprint polygons intersect the coastline."""
    ok = np.array([p is not None for p in polys])
    hit = np.zeros(len(polys), bool)
    idx = np.flatnonzero(ok)
    pairs = gshhg.coast_tree.query(polys[idx], predicate="intersects")
    hit[idx[np.unique(pairs[0])]] = True
    return hit


def coast_points_in_images(polys: np.ndarray, gshhg, step: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Coastline vertices (every ``step``-th candidate) inside each footprint: (image index (K,), lon/lat deg
    (K, 2)). Bounding-box candidates from the STRtree, then a vectorised point-in-polygon test."""
    import shapely

    ok = np.flatnonzero([p is not None for p in polys])
    pairs = gshhg.coast_tree.query(polys[ok])
    xy, start = gshhg.coast_coords()
    n = start[pairs[1] + 1] - start[pairs[1]]
    pt = np.repeat(start[pairs[1]] - np.cumsum(np.r_[0, n[:-1]]), n) + np.arange(n.sum())
    img = np.repeat(ok[pairs[0]], n)
    pt, img = pt[::step], img[::step]
    inside = shapely.contains_xy(polys[img], xy[pt, 0], xy[pt, 1])
    return img[inside], xy[pt[inside]]


def _sun_elevation_deg(lat_rad, lon_rad, jd) -> np.ndarray:
    """Sun elevation (deg) above the geodetic horizon at points (…) and Julian dates (…)."""
    s_eci, _ = sun_eci(jd)
    s_ecef = np.einsum("...ij,...j->...i", wgs84.R_ecef_from_eci(jd), s_eci)
    up = wgs84.R_ecef_from_enu(lat_rad, lon_rad)[..., 2]
    return np.degrees(np.arcsin(np.clip(np.sum(up * s_ecef, -1), -1, 1)))


def boundary_sun_elevation_deg(pos, R, jd, dirs) -> tuple[np.ndarray, np.ndarray]:
    """Lowest and highest sun elevation (deg) on each footprint's boundary loop: (N,), (N,)."""
    pts = footprint.footprint_points(pos, R, dirs)  # (N, M, 3)
    lat, lon, _ = wgs84.ecef_to_geodetic(pts)
    el = _sun_elevation_deg(lat, lon, np.repeat(np.asarray(jd)[:, None], pts.shape[1], 1))
    el = np.where(np.isfinite(el), el, np.nan)
    return np.nanmin(el, 1), np.nanmax(el, 1)


def visible_images(incl_deg: float, fov_deg: float, opt: VisibilityOptions, gshhg, *, track=None,
                   known: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[dict, tuple[np.ndarray, np.ndarray]]:
    """Counts for one (inclination, FOV): images, with coastline, with lit/clear coastline.

    ``known`` = (coast, usable) masks already established for a *smaller* FOV of the same track: a
    footprint contains every smaller one, so those images are positive without a query.
    Returns (row, (coast, usable))."""
    pos, R, t, jd = track if track is not None else nadir_track(incl_deg, opt)
    dirs = footprint.boundary_dirs_fov(np.radians(fov_deg), n_per_edge=opt.n_per_edge)
    coast = np.zeros(len(t), bool) if known is None else known[0].copy()
    usable = np.zeros(len(t), bool) if known is None else known[1].copy()
    todo = np.flatnonzero(~coast)
    polys = np.empty(len(t), dtype=object)
    polys[:] = footprint.footprint_polygons(pos, R, dirs) if len(todo) == len(t) else None
    if len(todo) < len(t):
        polys[todo] = footprint.footprint_polygons(pos[todo], R[todo], dirs)
    coast[todo] = coast_in_images(polys[todo], gshhg)
    row = {"inclination_deg": incl_deg, "fov_deg": fov_deg, "n_images": len(t), "n_coast": int(coast.sum()),
           "fraction_coast": float(coast.mean())}
    if opt.daylight_only or opt.cloud_cover > 0:
        need = np.flatnonzero(coast & ~usable)
        check_sun = np.zeros(len(t), bool)
        if opt.daylight_only and len(need):
            lo, hi = boundary_sun_elevation_deg(pos[need], R[need], jd[need], dirs)
            lit = lo > opt.min_sun_elevation_deg + SUN_MARGIN_DEG
            dark = hi < opt.min_sun_elevation_deg - SUN_MARGIN_DEG
            check_sun[need[~lit & ~dark]] = True
            if opt.cloud_cover <= 0:
                usable[need[lit]] = True
                need = need[~lit & ~dark]
            else:
                need = need[~dark]
        miss = need[np.array([polys[i] is None for i in need], bool)]
        if len(miss):
            polys[miss] = footprint.footprint_polygons(pos[miss], R[miss], dirs)
        img, ll = coast_points_in_images(polys[need], gshhg, CLOUD_THIN if opt.cloud_cover > 0 else 1)
        img = need[img]
        good = np.ones(len(img), bool)
        sel = np.flatnonzero(check_sun[img])
        if len(sel):
            lat, lon = np.radians(ll[sel, 1]), np.radians(ll[sel, 0])
            good[sel] = _sun_elevation_deg(lat, lon, jd[img[sel]]) > opt.min_sun_elevation_deg
        if opt.cloud_cover > 0:
            keep = np.flatnonzero(good)
            p = wgs84.geodetic_to_ecef(np.radians(ll[keep, 1]), np.radians(ll[keep, 0]))
            good[keep] = ~CloudField(opt.cloud_cover, opt.seed).cloudy(p)
        usable[np.unique(img[good])] = True
        row.update(n_usable=int(usable.sum()), fraction_usable=float(usable.mean()))
    return row, (coast, usable)


def visibility_sweep(inclinations_deg, fovs_deg, opt: VisibilityOptions, gshhg, progress: bool = True) -> list[dict]:
    """Rows of :func:`visible_images` for every (inclination, FOV) pair."""
    from tqdm import tqdm

    rows = []
    fovs = sorted(float(f) for f in fovs_deg)
    with tqdm(total=len(inclinations_deg) * len(fovs), desc="visibility", unit="case", disable=not progress) as bar:
        for inc in inclinations_deg:
            track, known = nadir_track(float(inc), opt), None
            for fov in fovs:  # ascending: positives of a smaller FOV carry over
                row, known = visible_images(float(inc), fov, opt, gshhg, track=track, known=known)
                rows.append(row)
                bar.update()
    return rows
