"""WGS-84, sun ephemeris and footprints against independent closed forms (paper eq. 1, spherical geometry,
scipy root finding on the ellipsoid)."""

from __future__ import annotations

import numpy as np
from scipy.optimize import brentq

from renderlab.dynamics.orbits import nadir_attitude
from renderlab.worlds.earth import footprint, wgs84
from renderlab.worlds.earth.sun import sun_eci


def test_geodetic_round_trip():
    rng = np.random.default_rng(1)
    lat, lon, h = rng.uniform(-1.5, 1.5, 200), rng.uniform(-3, 3, 200), rng.uniform(-1e3, 2e6, 200)
    la, lo, hh = wgs84.ecef_to_geodetic(wgs84.geodetic_to_ecef(lat, lon, h))
    assert np.abs(la - lat).max() < 1e-10 and np.abs(lo - lon).max() < 1e-12 and np.abs(hh - h).max() < 1e-4


def test_ray_ellipsoid_matches_root_finding():
    rng = np.random.default_rng(2)
    o = wgs84.geodetic_to_ecef(0.7, 0.3, 800e3)
    for _ in range(20):
        d = -o / np.linalg.norm(o) + rng.normal(0, 0.3, 3)
        d /= np.linalg.norm(d)
        t = wgs84.ray_ellipsoid(o, d)
        if not np.isfinite(t):
            continue
        def f(s, o=o, d=d):
            return (((o + s * d) / [wgs84.A, wgs84.A, wgs84.B]) ** 2).sum() - 1

        assert abs(t - brentq(f, 0, t * 1.0000001 + 1)) < 1e-3 or abs(t - brentq(f, 0, t + 1e-3)) < 1e-3


def test_sun_at_june_solstice_and_march_equinox():
    """At the published (USNO, to the minute) 2024 equinox and solstice the apparent sun, rotated from GCRF to the
    true equator and equinox of date by ERFA's IAU 2006/2000A NPB matrix (``pnm06a``, not used by the lab's sun),
    has declination 0 and the true obliquity ε_A + Δε (``obl06``, ``nut06a``): ±30 s of rounding is ±0.5″ of
    declination at the equinox, the sun's ecliptic latitude ≤ 1″."""
    import erfa
    from astropy.time import Time

    def true_of_date(iso):
        tt = Time(iso, scale="utc").tt
        u, r = sun_eci(wgs84.julian_date(wgs84.parse_epoch(iso + "Z")))
        return erfa.pnm06a(tt.jd1, tt.jd2) @ u, r, tt

    u, r, tt = true_of_date("2024-06-20T20:51:00")
    eps = erfa.obl06(tt.jd1, tt.jd2) + erfa.nut06a(tt.jd1, tt.jd2)[1]
    arcsec = np.degrees(1.0) * 3600
    assert abs(np.arcsin(u[2]) - eps) * arcsec < 2.0 and abs(np.arctan2(u[1], u[0]) - np.pi / 2) * arcsec < 2.0
    assert abs(r - 1.0163) < 1e-3
    u, _, _ = true_of_date("2024-03-20T03:06:00")
    assert abs(np.arcsin(u[2])) * arcsec < 2.0 and abs(np.arctan2(u[1], u[0])) * arcsec < 2.0


def test_footprint_vs_eq1_and_spherical_closed_form():
    h, fov = 1000e3, np.radians(30)
    pos = wgs84.geodetic_to_ecef(0.0, 0.0, h)[None]
    R = nadir_attitude(pos, np.array([[0, 0, 7000.0]]))
    dirs = footprint.boundary_dirs_fov(fov, n_per_edge=2)  # corners and edge midpoints
    pts = footprint.footprint_points(pos, R, dirs)[0]
    lat, lon, hh = wgs84.ecef_to_geodetic(pts)
    assert np.abs(hh).max() < 1e-3
    # edge midpoints: along-track (north-south) and cross-track (east-west) ground half-widths
    mid_y = np.linalg.norm(pts[0 + 1] - pts[4 + 1])  # top-edge midpoint to bottom-edge midpoint (chord)
    mid_x = np.linalg.norm(pts[2 + 1] - pts[6 + 1])
    # sphere of the local radius of curvature (east-west: N = a; north-south at the equator: M = a(1-e²)): central half angle lam = asin((R+h)/R sin(eta)) - eta
    for chord, Rloc in ((mid_x, wgs84.A), (mid_y, wgs84.A * (1 - wgs84.E2))):
        lam = np.arcsin((Rloc + h) / Rloc * np.sin(fov / 2)) - fov / 2
        assert abs(chord - 2 * Rloc * np.sin(lam)) / chord < 2e-3
    # eq. 1 is the flat-Earth size: the exact ground arc is larger by the curvature (measured 0.60 % at 1000 km, 30 deg)
    gfov = footprint.gfov_eq1(h, fov)
    assert abs(gfov - 535.9e3) < 0.1e3  # the paper's "approximately 536 km"
    arc = 2 * wgs84.A * np.arcsin(mid_x / (2 * wgs84.A))
    assert 1.004 < arc / gfov < 1.007
    # small FOV: exact → eq. 1
    pts = footprint.footprint_points(pos, R, footprint.boundary_dirs_fov(np.radians(1), n_per_edge=2))[0]
    assert abs(np.linalg.norm(pts[3] - pts[7]) / footprint.gfov_eq1(h, np.radians(1)) - 1) < 1e-4


def test_footprint_polygons_antimeridian_and_pole():
    pos = wgs84.geodetic_to_ecef(np.radians([0, 89.8, 10]), np.radians([0, 20, 179.9]), 1000e3)
    R = nadir_attitude(pos, np.cross([0, 0, 1.0], pos) + [0, 0, 7000.0])
    polys = footprint.footprint_polygons(pos, R, footprint.boundary_dirs_fov(np.radians(30)))
    assert polys[0].geom_type == "Polygon" and polys[0].contains(__import__("shapely").Point(0, 0))
    assert polys[1].bounds[3] == 90.0 and polys[1].bounds[0] == -180.0  # pole cap
    assert polys[2].geom_type == "MultiPolygon" and polys[2].bounds[0] == -180.0 and polys[2].bounds[2] == 180.0
    assert all(p.is_valid for p in polys)


def test_footprint_exact_on_the_ellipsoid_at_45_deg_latitude_500_km():
    """Every boundary point is where its camera ray first meets WGS-84 (scipy brentq on the implicit ellipsoid
    along the ray, from the camera); the footprint's width (edge midpoint to edge midpoint) is the closed form on
    the sphere of the local Gaussian radius √(MN), and exceeds eq. 1 by the curvature: 0.28 % at 30°, 0.008 % at
    5° (measured agreement with the sphere: ≤ 1.1e-5 relative)."""
    h = 500e3
    pos = wgs84.geodetic_to_ecef(np.radians(45.0), np.radians(-30.0), h)[None]
    vel = np.cross([0, 0, 1.0], pos[0]) + [0, 0, 7600.0]
    R = nadir_attitude(pos, vel[None])
    s2 = np.sin(np.radians(45.0)) ** 2
    R_gauss = np.sqrt(wgs84.A / np.sqrt(1 - wgs84.E2 * s2) * wgs84.A * (1 - wgs84.E2) / (1 - wgs84.E2 * s2) ** 1.5)
    for fov_deg in (30.0, 5.0):
        fov = np.radians(fov_deg)
        dirs = footprint.boundary_dirs_fov(fov, n_per_edge=4)
        pts = footprint.footprint_points(pos, R, dirs)[0]
        d_ecef = dirs @ R[0].T
        for p, d in zip(pts, d_ecef):
            def f(s, d=d):
                return (((pos[0] + s * d) / [wgs84.A, wgs84.A, wgs84.B]) ** 2).sum() - 1

            t_ref = brentq(f, 0.0, np.linalg.norm(p - pos[0]) * 1.01)    # f > 0 at the camera, < 0 inside
            assert abs(np.linalg.norm(p - pos[0]) - t_ref) < 1e-3
        # edge midpoints (indices 2, 6, 10, 14 of the 16-point loop): opposite pairs span the footprint
        lam = np.arcsin((R_gauss + h) / R_gauss * np.sin(fov / 2)) - fov / 2     # half central angle
        sphere = 2 * R_gauss * np.sin(lam)
        for w in (np.linalg.norm(pts[2] - pts[10]), np.linalg.norm(pts[6] - pts[14])):
            assert abs(w / sphere - 1) < 5e-5, (fov_deg, w / sphere - 1)
            assert w > footprint.gfov_eq1(h, fov) * (1 + 0.9 * (sphere / footprint.gfov_eq1(h, fov) - 1))


def test_land_raster_samples_pixel_centres_exactly():
    """The albedo raster's even-odd scanline fill against matplotlib's point-in-path test at every pixel centre
    (random star polygons with a hole, sub-pixel vertices), and its area against the shoelace area: unbiased
    (cv2.fillPoly, used before, dilated land by 0.45 px x perimeter; see tiles.fill_even_odd)."""
    from matplotlib.path import Path

    from renderlab.worlds.earth.tiles import fill_even_odd

    rng = np.random.default_rng(5)
    H, W = 90, 110
    yy, xx = np.mgrid[0:H, 0:W]
    centres = np.c_[xx.ravel(), yy.ravel()].astype(float)
    excess = []
    for _ in range(40):
        c, r = rng.uniform(40, 60, 2), rng.uniform(15, 35)
        ang = np.sort(rng.uniform(0, 2 * np.pi, 60))
        outer = np.c_[c[0] + r * (1 + 0.3 * rng.uniform(-1, 1, 60)) * np.cos(ang),
                      c[1] + r * (1 + 0.3 * rng.uniform(-1, 1, 60)) * np.sin(ang)]
        hole = c + 0.3 * r * np.c_[np.cos(ang[::-1]), np.sin(ang[::-1])][::4]
        outer, hole = np.vstack([outer, outer[:1]]), np.vstack([hole, hole[:1]])
        outer[3] = [outer[3, 0], 50.0]                              # a vertex exactly on a row of centres
        got = fill_even_odd((H, W), [outer, hole])
        ref = (Path(outer).contains_points(centres) & ~Path(hole).contains_points(centres)).reshape(H, W)
        assert np.sum(got != ref) <= 2                              # ties: a centre exactly on an edge
        area = lambda p: 0.5 * abs(np.dot(p[:-1, 0], p[1:, 1]) - np.dot(p[:-1, 1], p[1:, 0]))  # noqa: E731
        perim = np.sum(np.linalg.norm(np.diff(outer, axis=0), axis=1)) + np.sum(np.linalg.norm(np.diff(hole, axis=0), axis=1))
        excess.append((got.sum() - (area(outer) - area(hole))) / perim)
    print(f"raster area - polygon area, per unit perimeter: mean {np.mean(excess):+.4f} px, sd {np.std(excess):.4f}")
    assert abs(np.mean(excess)) < 0.02
