r"""Camera footprints on the WGS-84 ellipsoid, and their lon/lat polygons.

Theory
------
Straub & Christian eq. 1 gives the flat-Earth size of a nadir footprint, GFOV = 2 h tan(FOV/2). The exact
footprint is where the rays of the image boundary meet the ellipsoid (:func:`wgs84.ray_ellipsoid`); on a
sphere of radius R the ground half-width of a nadir view is R·(asin((R+h)/R · sin(FOV/2)) − FOV/2) of arc,
larger than eq. 1 by the Earth's curvature (0.60 % at 1000 km and 30° across track on the equator, more at wider FOVs).

A footprint polygon in lon/lat is the boundary loop sampled densely (its edges are curves in lon/lat),
with longitudes unwrapped along the loop; a loop that winds once around the pole is closed through that
pole, and pieces beyond ±180° are shifted back (the result is a MultiPolygon across the antimeridian).
"""

from __future__ import annotations

import numpy as np

from renderlab.worlds.earth import wgs84


def gfov_eq1(altitude_m, fov_rad) -> np.ndarray:
    """Paper eq. 1: flat-Earth ground field of view 2 h tan(FOV/2)."""
    return 2.0 * np.asarray(altitude_m, float) * np.tan(np.asarray(fov_rad, float) / 2.0)


def boundary_dirs_fov(fov_x_rad: float, fov_y_rad: float | None = None, n_per_edge: int = 16) -> np.ndarray:
    """Camera-frame directions (M, 3) around the edge of a pinhole image with full FOVs (x, y), starting at
    the top-left corner, going right (clockwise in the image)."""
    tx = np.tan(fov_x_rad / 2)
    ty = np.tan((fov_y_rad if fov_y_rad is not None else fov_x_rad) / 2)
    f = np.linspace(-1.0, 1.0, n_per_edge + 1)[:-1]
    x = np.concatenate([f * tx, np.full(n_per_edge, tx), -f * tx, np.full(n_per_edge, -tx)])
    y = np.concatenate([np.full(n_per_edge, -ty), f * ty, np.full(n_per_edge, ty), -f * ty])
    d = np.stack([x, y, np.ones_like(x)], -1)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def boundary_dirs_camera(camera, n_per_edge: int = 16, margin_px: float = 0.0) -> np.ndarray:
    """Camera-frame unit directions (M, 3) around the image edge (pixel edges −½ … W−½, widened by
    ``margin_px``) of a :class:`renderlab.geometry.CameraModel` (distortion included)."""
    W, H = camera.width, camera.height
    s0, s1, l0, l1 = -0.5 - margin_px, W - 0.5 + margin_px, -0.5 - margin_px, H - 0.5 + margin_px
    f = np.linspace(0.0, 1.0, n_per_edge + 1)[:-1]
    s = np.concatenate([s0 + f * (s1 - s0), np.full(n_per_edge, s1), s1 - f * (s1 - s0), np.full(n_per_edge, s0)])
    ln = np.concatenate([np.full(n_per_edge, l0), l0 + f * (l1 - l0), np.full(n_per_edge, l1), l1 - f * (l1 - l0)])
    d = camera.unproject(np.stack([s, ln], -1))
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def footprint_points(pos_ecef: np.ndarray, R_ecef_from_cam: np.ndarray, dirs_cam: np.ndarray) -> np.ndarray:
    """Ground points (N, M, 3) ECEF where rays ``dirs_cam`` (M, 3) from N cameras meet the ellipsoid
    (NaN where a ray misses). pos (N, 3), R (N, 3, 3)."""
    pos = np.atleast_2d(pos_ecef)
    R = np.asarray(R_ecef_from_cam, float).reshape(-1, 3, 3)
    d = np.einsum("nij,mj->nmi", R, dirs_cam)
    t = wgs84.ray_ellipsoid(pos[:, None, :], d)
    return pos[:, None, :] + t[..., None] * d


def lonlat_polygons(lon_deg: np.ndarray, lat_deg: np.ndarray) -> np.ndarray:
    """Shapely (Multi)Polygons in lon/lat (−180…180) of N boundary loops (N, M) (NaN rows → None)."""
    import shapely
    import shapely.affinity

    lon = np.atleast_2d(lon_deg)
    lat = np.atleast_2d(lat_deg)
    out = np.empty(len(lon), dtype=object)
    world = shapely.box(-180.0, -90.0, 180.0, 90.0)
    finite = np.all(np.isfinite(lon), axis=1)
    span = np.degrees(np.angle(np.exp(1j * np.radians(np.diff(np.c_[lon, lon[:, :1]], axis=1)))))
    simple = finite & (np.abs(np.diff(lon, axis=1)).max(axis=1, initial=0) < 90.0) & (np.abs(span.sum(1)) < 180.0)
    simple &= np.abs(lon[:, :1] - lon[:, -1:]).ravel() < 90.0
    if simple.any():  # no antimeridian crossing, no pole: one vectorised GEOS call
        ring = np.concatenate([lon[simple], lon[simple][:, :1]], 1), np.concatenate([lat[simple], lat[simple][:, :1]], 1)
        out[simple] = shapely.polygons(np.stack(ring, -1))
    for k in np.flatnonzero(~simple):
        if not np.all(np.isfinite(lon[k])):
            out[k] = None
            continue
        lo = np.degrees(np.unwrap(np.radians(lon[k])))
        la = lat[k]
        wind = np.degrees(np.angle(np.exp(1j * np.radians(lon[k][0] - lon[k][-1])))) + lo[-1] - lo[0]
        if abs(wind) > 180.0:  # the loop winds around a pole: close it through the pole
            pole = 90.0 if np.mean(la) > 0 else -90.0
            lo_end = lo[0] + wind
            lo = np.concatenate([lo, [lo_end, lo_end, lo[0]]])
            la = np.concatenate([la, [la[0], pole, pole]])
            shift = np.floor((lo.min() + 180.0) / 360.0) * 360.0
            lo = lo - shift
            poly = shapely.make_valid(shapely.Polygon(np.stack([lo, la], -1)))
            parts = [shapely.intersection(shapely.affinity.translate(poly, dx), world) for dx in (0.0, -360.0, 360.0)]
        else:
            lo = lo - np.round(np.mean(lo) / 360.0) * 360.0
            poly = shapely.Polygon(np.stack([lo, la], -1))
            if not poly.is_valid:
                poly = shapely.make_valid(poly)
            if lo.min() >= -180.0 and lo.max() <= 180.0:
                out[k] = poly
                continue
            parts = [shapely.intersection(shapely.affinity.translate(poly, dx), world) for dx in (0.0, -360.0, 360.0)]
        out[k] = shapely.union_all([p for p in parts if not p.is_empty])
    return out


def footprint_polygons(pos_ecef, R_ecef_from_cam, dirs_cam) -> np.ndarray:
    """Lon/lat footprint polygons (N,) of N cameras with boundary rays ``dirs_cam``."""
    pts = footprint_points(pos_ecef, R_ecef_from_cam, dirs_cam)
    lat, lon, _ = wgs84.ecef_to_geodetic(pts)
    return lonlat_polygons(np.degrees(lon), np.degrees(lat))
