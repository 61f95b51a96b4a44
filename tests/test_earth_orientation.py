"""Earth orientation (GCRF → ITRF) and the sun against astropy's own, independent code paths.

Oracles: ``astropy.coordinates`` GCRS ↔ ITRS transforms of ground and LEO points (astropy's frame graph, its own
EOP look-up and time scales; the lab calls ERFA ``c2t06a`` directly), astropy's ``get_body("sun")`` and
``get_sun``, astropy ``Time.delta_ut1_utc``, and a finite difference for the Earth-fixed velocity. The epochs are
400 random instants of 2024, all transformed at once.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from renderlab.worlds.earth import orientation, wgs84
from renderlab.worlds.earth.sun import sun_eci, sun_gcrf

ARCSEC = np.degrees(1.0) * 3600.0
EPOCH = wgs84.parse_epoch("2024-01-01T00:00:00Z")


@pytest.fixture(scope="module")
def year():
    rng = np.random.default_rng(2024)
    t = np.sort(rng.uniform(0.0, 366 * 86400.0, 400))
    return t, orientation.earth_orientation(EPOCH, t), rng


def _astropy_itrs_to_gcrs(p_itrf, time):
    import astropy.units as u
    from astropy.coordinates import GCRS, ITRS, CartesianRepresentation

    itrs = ITRS(CartesianRepresentation(p_itrf.T * u.m), obstime=time)
    return itrs.transform_to(GCRS(obstime=time)).cartesian.xyz.to_value(u.m).T


def _astropy_gcrs_to_itrs(p_gcrf, time):
    import astropy.units as u
    from astropy.coordinates import GCRS, ITRS, CartesianRepresentation

    gcrs = GCRS(CartesianRepresentation(p_gcrf.T * u.m), obstime=time)
    return gcrs.transform_to(ITRS(obstime=time)).cartesian.xyz.to_value(u.m).T


def test_no_downloads_and_the_bundled_tables_cover_2024(year):
    from astropy.utils import iers

    _, eo, _ = year
    assert iers.conf.auto_download is False
    assert eo.eop_in_table.all()
    ref = eo.time.delta_ut1_utc                                   # astropy's own UT1-UTC look-up
    assert np.abs(eo.ut1_minus_utc_s - ref).max() < 1e-9
    assert 0.0 < np.abs(eo.xp_rad).max() * ARCSEC < 0.5 and 0.1 < np.abs(eo.yp_rad).max() * ARCSEC < 0.6
    R = eo.R_itrf_from_gcrf
    assert np.abs(R @ np.swapaxes(R, 1, 2) - np.eye(3)).max() < 1e-14 and np.allclose(np.linalg.det(R), 1.0)


@pytest.mark.parametrize("height_m", [0.0, 500e3, 1000e3])
def test_ground_and_leo_points_match_astropy_gcrs_itrs(year, height_m):
    """Acceptance: ≤ 0.5 m on the ground and at LEO over 2024, both directions (measured: nanometres)."""
    _, eo, rng = year
    lat, lon = np.arcsin(rng.uniform(-1, 1, len(eo.time))), rng.uniform(-np.pi, np.pi, len(eo.time))
    p_itrf = wgs84.geodetic_to_ecef(lat, lon, height_m)
    p_gcrf = _astropy_itrs_to_gcrs(p_itrf, eo.time)
    err = np.linalg.norm(eo.to_itrf(p_gcrf) - p_itrf, axis=1)
    back = np.linalg.norm(np.einsum("nji,nj->ni", eo.R_itrf_from_gcrf, p_itrf) - p_gcrf, axis=1)
    fwd = np.linalg.norm(_astropy_gcrs_to_itrs(p_gcrf, eo.time) - p_itrf, axis=1)
    print(f"h = {height_m / 1e3:.0f} km: lab vs astropy GCRS→ITRS max {err.max():.2e} m, median "
          f"{np.median(err):.2e} m; ITRF→GCRF max {back.max():.2e} m (astropy round trip {fwd.max():.1e} m)")
    assert err.max() < 0.5 and back.max() < 0.5
    # what the frame change is about: the GCRF differs from the ITRF pole by precession-nutation (~0.2-0.4 deg)
    tilt = np.degrees(np.arccos(eo.pole_gcrf[:, 2]))
    assert np.all((tilt > 0.1) & (tilt < 0.5))


def test_float_julian_dates_and_wgs84_entry_point_agree(year):
    t, eo, _ = year
    R = wgs84.R_ecef_from_eci(wgs84.julian_date(EPOCH, t[:50]))
    ang = np.linalg.norm(R - eo.R_itrf_from_gcrf[:50], axis=(1, 2))      # ≈ rotation angle difference (rad)
    assert ang.max() * 6378137.0 < 0.05                                 # 40 µs float JD resolution → ≤ 2 cm
    assert orientation.earth_orientation(EPOCH, t) is eo                # cached per epoch grid


def test_earth_fixed_velocity_of_a_ground_point_is_zero():
    """A point fixed in ITRF, moved to GCRF at t ± h and differenced, has zero ITRF velocity (< 1 mm/s)."""
    p_itrf = wgs84.geodetic_to_ecef(np.radians(38.7), np.radians(-9.1), 1000e3)
    t, h = np.array([3600.0]), 0.5
    eo3 = orientation.earth_orientation(EPOCH, np.r_[t - h, t, t + h])
    g = np.einsum("nji,j->ni", eo3.R_itrf_from_gcrf, p_itrf)
    v_gcrf = (g[2] - g[0]) / (2 * h)
    eo = orientation.earth_orientation(EPOCH, t)
    r, v = eo.to_itrf(g[1][None], v_gcrf[None])
    assert np.linalg.norm(r[0] - p_itrf) < 1e-6 and np.linalg.norm(v[0]) < 1e-3


@pytest.mark.filterwarnings("ignore::erfa.ErfaWarning")      # 2040: "dubious year" (future leap seconds unknown)
def test_fallback_outside_the_tables_warns_and_uses_zero_eop():
    with pytest.warns(orientation.EOPRangeWarning, match="UT1-UTC = 0"):
        eo = orientation.earth_orientation(wgs84.parse_epoch("2040-01-01T00:00:00Z"), [0.0, 60.0])
    assert not eo.eop_in_table.any() and np.all(eo.ut1_minus_utc_s == 0) and np.all(eo.xp_rad == 0)
    assert "outside" in eo.record(0)["eop_source"]
    with warnings.catch_warnings():
        warnings.simplefilter("error", orientation.EOPRangeWarning)
        orientation.earth_orientation(wgs84.parse_epoch("2024-06-21T10:00:00Z"), [0.0])


def test_sun_direction_within_5_arcsec_of_astropy(year):
    from astropy.coordinates import get_body, get_sun

    _, eo, _ = year
    u, dist = sun_gcrf(eo.time)
    body = get_body("sun", eo.time)
    for name, ref in (("get_body", body), ("get_sun", get_sun(eo.time))):
        c = ref.cartesian.xyz.value.T
        c = c / np.linalg.norm(c, axis=1, keepdims=True)
        ang = np.arccos(np.clip(np.sum(c * u, 1), -1, 1)) * ARCSEC
        print(f"sun vs astropy {name}: max {ang.max():.3f}″, median {np.median(ang):.3f}″")
        assert ang.max() < 5.0
    assert np.abs(dist - body.distance.to_value("au")).max() < 1e-6
    u2, d2 = sun_eci(wgs84.julian_date(EPOCH, np.asarray(year[0])))     # float-JD entry point
    assert np.arccos(np.clip(np.sum(u2 * u, 1), -1, 1)).max() * ARCSEC < 0.01 and np.allclose(d2, dist)


def test_earth_plan_names_its_frames_and_matches_astropy(repo):
    """The Earth world's frame records: GCRF / ITRF / ENU_TILE named, r_ecef = astropy's ITRS of r_eci, the
    sun in ITRF = astropy's sun transformed to ITRS (≤ 5″), EOP recorded."""
    import astropy.units as u
    from astropy.coordinates import ITRS, get_body
    from astropy.time import Time

    from renderlab.render.scene import SceneDescription
    from renderlab.scenario import load_scenario
    from renderlab.worlds.earth.plan import EarthPlan

    sc, _ = load_scenario(repo / "scenes/earth_leo.toml", ["trajectory.frames=3", "trajectory.dt_s=600"])
    plan = EarthPlan.from_scenario(sc)
    assert plan.render_frame == {"name": "ENU_TILE", "parent_frame": "ITRF", "inertial_frame": "GCRF"}
    recs = [plan.frame_meta(f, SceneDescription(bodies=[])) for f in plan.frames]
    times = Time([r["epoch_utc"].replace("Z", "") for r in recs], scale="utc")
    r_eci = np.array([r["spacecraft"]["r_eci_m"] for r in recs])
    r_ecef = np.array([r["spacecraft"]["r_ecef_m"] for r in recs])
    assert np.linalg.norm(_astropy_gcrs_to_itrs(r_eci, times) - r_ecef, axis=1).max() < 0.5
    sun_itrs = get_body("sun", times).transform_to(ITRS(obstime=times)).cartesian.xyz.to_value(u.m).T
    sun_itrs /= np.linalg.norm(sun_itrs, axis=1, keepdims=True)
    ang = np.arccos(np.clip(np.sum(sun_itrs * np.array([r["sun_ecef"] for r in recs]), 1), -1, 1)) * ARCSEC
    assert ang.max() < 5.0
    for r in recs:
        assert r["frames"]["inertial"] == "GCRF" and r["frames"]["earth_fixed"] == "ITRF"
        assert r["render_frame"]["name"] == "ENU_TILE" and r["render_frame"]["parent_frame"] == "ITRF"
        assert r["earth_orientation"]["eop_source"].startswith("astropy bundled")
        assert r["truth_orbit_model"] == "kepler_two_body"
