r"""Coastline visibility (Straub & Christian Fig. 4): the share of images that contain coastline.

For a circular orbit (two-body, eqs. 10-12) images are taken every ``cadence_s`` for ``hours``; the camera
points at nadir (:func:`renderlab.dynamics.orbits.nadir_attitude`). Each image's exact footprint is the
loop where its boundary rays meet the WGS-84 ellipsoid (the paper's eq. 1 gives its flat-Earth size); an
image *contains coastline* when that polygon intersects the full-resolution GSHHG coastline (STRtree
query, one vectorised GEOS call per footprint batch). Options: *daylight* keeps only coast points with the
sun above ``min_sun_elevation_deg`` (real sun for the epoch); *clouds* hides coast points under a seeded
:class:`~renderlab.worlds.earth.clouds.CloudField` with the given cover fraction. An image then counts when
at least one coast point inside it is lit and clear.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from renderlab.dynamics.orbits import OrbitElements, nadir_attitude
from renderlab.worlds.earth import footprint, wgs84
from renderlab.worlds.earth.clouds import CloudField
from renderlab.worlds.earth.sun import sun_eci


CLOUD_THIN = 8


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


def coast_points_in_images(polys: np.ndarray, gshhg) -> tuple[np.ndarray, np.ndarray]:
    """All coastline vertices inside each footprint: (image index (K,), lon/lat deg (K, 2)).
    Bounding-box candidates from the STRtree, then a vectorised point-in-polygon test."""
    import shapely

    ok = np.flatnonzero([p is not None for p in polys])
    pairs = gshhg.coast_tree.query(polys[ok])
    xy, start = gshhg.coast_coords()
    n = start[pairs[1] + 1] - start[pairs[1]]
    pt = np.repeat(start[pairs[1]] - np.cumsum(np.r_[0, n[:-1]]), n) + np.arange(n.sum())
    img = np.repeat(ok[pairs[0]], n)
    inside = shapely.contains_xy(polys[img], xy[pt, 0], xy[pt, 1])
    return img[inside], xy[pt[inside]]


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
        if len(need) and polys[need[0]] is None:
            polys[need] = footprint.footprint_polygons(pos[need], R[need], dirs)
        img, ll = coast_points_in_images(polys[need], gshhg)
        img = need[img]
        p = wgs84.geodetic_to_ecef(np.radians(ll[:, 1]), np.radians(ll[:, 0]))
        good = np.ones(len(img), bool)
        if opt.daylight_only:
            s_eci, _ = sun_eci(jd[img])
            s_ecef = np.einsum("nij,nj->ni", wgs84.R_ecef_from_eci(jd[img]), s_eci)
            up = wgs84.R_ecef_from_enu(np.radians(ll[:, 1]), np.radians(ll[:, 0]))[..., 2]
            good &= np.sum(up * s_ecef, -1) > np.sin(np.radians(opt.min_sun_elevation_deg))
        if opt.cloud_cover > 0:  # the field is smooth at ≥ 20 km: test every 8th vertex (≈ 1 km apart)
            keep = np.flatnonzero(good)[::CLOUD_THIN]
            good[:] = False
            good[keep] = ~CloudField(opt.cloud_cover, opt.seed).cloudy(p[keep])
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
