"""Coastline visibility (paper Fig. 4): which nadir images contain coastline, lit coastline, clear coastline.

Oracle: an independent route through the camera instead of lon/lat polygons — GSHHG coastline vertices (the
geometric study's KD-tree, thinned to one per 1 km cube) near the sub-satellite point are projected with the
image's true pose; an image contains coastline when a vertex that faces the camera falls inside the square field
of view. Lighting per vertex from the sun's direction and the ellipsoid normal (no terminator shortcut), clouds per
vertex (every vertex, not every 8th). The two routes differ only where a coastline stretch grazes a footprint
edge within a vertex spacing, so a couple of images in a few hundred may disagree.
"""

from __future__ import annotations

import math

import earth_fixtures
import numpy as np
import pytest

from renderlab.worlds.earth import wgs84
from renderlab.worlds.earth.clouds import CloudField
from renderlab.worlds.earth.sun import sun_eci
from renderlab.worlds.earth.visibility import VisibilityOptions, nadir_track, visibility_sweep, visible_images

gshhg = earth_fixtures.gshhg
OPT = VisibilityOptions(hours=4.0, cadence_s=60.0, epoch_utc="2024-06-21T10:00:00Z")   # 240 images


@pytest.fixture(scope="module")
def coast_points(gshhg):
    from renderlab.worlds.earth.coast_points import coastline_points

    return coastline_points(1000.0)


def _oracle(track, fov_deg, db, jd=None, min_elev_deg=None, clouds=None):
    """(contains coast, contains lit/clear coast) per image, by projecting coast vertices with the true camera."""
    pos, R, _, jds = track
    tan_half = math.tan(math.radians(fov_deg) / 2)
    eta = math.atan(math.sqrt(2.0) * tan_half)                      # the corner ray's off-nadir angle
    h = np.linalg.norm(pos[0]) - wgs84.B
    lam = math.asin(min(1.0, (wgs84.A + h) / wgs84.B * math.sin(eta))) - eta
    radius = 2.0 * wgs84.A * math.sin(lam / 2) * 1.2 + 30e3           # a generous chord around nadir
    coast, usable = np.zeros(len(pos), bool), np.zeros(len(pos), bool)
    for k in range(len(pos)):
        sub = pos[k] / np.linalg.norm(pos[k]) * wgs84.A
        idx = np.asarray(db.tree.query_ball_point(sub, radius), dtype=np.int64)
        p = db.ecef_m[idx]
        pc = (p - pos[k]) @ R[k]
        facing = np.einsum("ij,ij->i", db.normal[idx], pos[k] - p) > 0
        inside = facing & (pc[:, 2] > 0) & (np.abs(pc[:, 0]) <= tan_half * pc[:, 2]) & \
            (np.abs(pc[:, 1]) <= tan_half * pc[:, 2])
        coast[k] = inside.any()
        ok = inside
        if min_elev_deg is not None:
            s_ecef = wgs84.R_ecef_from_eci(jds[k]) @ sun_eci(jds[k])[0]
            ok = ok & (db.normal[idx] @ s_ecef > math.sin(math.radians(min_elev_deg)))
        if clouds is not None and ok.any():
            ok[ok] = ~clouds.cloudy(p[ok])
        usable[k] = ok.any()
    return coast, usable


@pytest.mark.parametrize("incl, fov", [(45.0, 30.0), (90.0, 10.0), (0.0, 5.0)])
def test_images_with_coastline_match_projected_gshhg(gshhg, coast_points, incl, fov):
    track = nadir_track(incl, OPT)
    row, (coast, _) = visible_images(incl, fov, OPT, gshhg, track=track)
    ref, _ = _oracle(track, fov, coast_points)
    bad = int(np.sum(coast != ref))
    print(f"i = {incl:.0f}°, FOV {fov:.0f}°: {coast.sum()} of {len(coast)} images with coastline, oracle "
          f"{ref.sum()}, {bad} disagree")
    assert 0.05 < ref.mean() < 0.95, "the track must see both coast and open sea"
    assert row["n_coast"] == int(coast.sum()) and row["fraction_coast"] == pytest.approx(coast.mean())
    assert bad <= 2


def test_daylight_and_clouds_match_per_point_oracle(gshhg, coast_points):
    incl, fov = 45.0, 30.0
    track = nadir_track(incl, OPT)
    for opt, clouds in ((VisibilityOptions(**{**OPT.__dict__, "daylight_only": True}), None),
                        (VisibilityOptions(**{**OPT.__dict__, "daylight_only": True, "cloud_cover": 0.67}),
                         CloudField(0.67, 0))):
        row, (coast, usable) = visible_images(incl, fov, opt, gshhg, track=track)
        ref_c, ref_u = _oracle(track, fov, coast_points, min_elev_deg=0.0, clouds=clouds)
        bad = int(np.sum(usable != ref_u))
        print(f"daylight, clouds {opt.cloud_cover}: usable {usable.sum()} (oracle {ref_u.sum()}) of {coast.sum()} "
              f"with coast; {bad} disagree")
        assert 0 < ref_u.sum() < ref_c.sum(), "the span must hold lit and dark coast"
        assert np.all(usable <= coast) and row["n_usable"] == int(usable.sum())
        assert bad <= 3


def test_sweep_carry_over_equals_independent_cases(gshhg):
    """The sweep reuses the positives of a smaller FOV for a larger one; each case alone gives the same counts."""
    rows = visibility_sweep([60.0], [30.0, 10.0, 20.0], OPT, gshhg, progress=False)
    assert [r["fov_deg"] for r in rows] == [10.0, 20.0, 30.0]
    for r in rows:
        alone, _ = visible_images(60.0, r["fov_deg"], OPT, gshhg)
        assert alone == r
    assert rows[0]["n_coast"] <= rows[1]["n_coast"] <= rows[2]["n_coast"]


def test_visibility_command(tmp_path, gshhg):
    from renderlab.cli import main

    out = tmp_path / "vis"
    assert main(["visibility", "--out", str(out), "--inclinations", "30,60", "--fovs", "10,30", "--hours", "1",
                 "--quiet"]) == 0
    lines = (out / "visibility.csv").read_text().splitlines()
    assert lines[0].startswith("inclination_deg,fov_deg,n_images,n_coast,fraction_coast") and len(lines) == 5
    assert (out / "visibility_contour.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("args, message", [
    (["--fovs", "abc"], "comma-separated list"), (["--inclinations", "200"], "--inclinations"),
    (["--cloud-cover", "1.5"], "--cloud-cover"), (["--epoch", "nope"], "--epoch"), (["--hours", "-1"], "--hours"),
])
def test_visibility_bad_arguments(tmp_path, capsys, args, message):
    from renderlab.cli import main

    assert main(["visibility", "--out", str(tmp_path / "v"), *args]) == 2
    err = capsys.readouterr().err
    assert err.startswith("renderlab: error:") and message in err and err.count("\n") == 1
    assert not (tmp_path / "v").exists()
