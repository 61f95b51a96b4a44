"""Study ``descent_navigation`` end to end on a tiny EV5 descent: ``renderlab campaign`` → ``renderlab report``.

A real Mitsuba render (64², 3 images 40 s apart near 90–65 m, 2 spp) through the truth cache; Retina and SPC each
drive the descent EKF closed-loop in 2 runs. Oracles, independent of the study's code:

* the true trajectory the study navigates against is the one the EV5 world rendered (manifest poses, 1e-6 m);
* every landmark's prediction is OpenCV's ``projectPoints`` of the maplet centre at the pose the filter gave the
  method (the row's a-priori position and star-tracker attitude);
* the first image's search distance is 3σ of the initial covariance projected by central differences of
  ``projectPoints`` (position block P0 and the star tracker's σ), clamped as configured;
* the reported errors are the filter's estimate minus the manifest position in the site's east-north-up axes;
* the report regenerates its CSVs and PNG+SVG figures from the tables alone.
"""

from __future__ import annotations

import csv
import json
import math

import cv2
import numpy as np
import pyarrow.parquet as pq
import pytest
from scipy.spatial.transform import Rotation
from tiny_ev5 import TINY_EV5_WORLD

from renderlab.cli import main

TINY = 'name = "ev5_descent_nav_tiny"\n' + TINY_EV5_WORLD + """[trajectory]
kind = "ev5_descent"
sampling = "rate"
start_time_s = 1300.0
frame_rate_hz = 0.025
frames = 3
[camera]
width = 64
height = 64
fx = 305.0
fy = 305.0
cx = 31.5
cy = 31.5
[render]
spp = 2
seed = 3
near_clip_m = 0.01
[campaign]
seed = 11
study = "descent_navigation"
[descent_navigation]
methods = ["retina", "spc"]
max_landmarks = 6
"""
RUNS = 2


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    d = tmp_path_factory.mktemp("dnav")
    (d / "tiny.toml").write_text(TINY)
    assert main(["campaign", str(d / "tiny.toml"), "--runs", str(RUNS), "--out", str(d / "camp"), "--workers", "0",
                 "--quiet"]) == 0
    assert main(["report", str(d / "camp"), "--out", str(d / "report")]) == 0
    runs = sorted((d / "camp" / "runs").iterdir())
    filt = [pq.read_table(r / "descent_filter.parquet").to_pydict() for r in runs]
    lms = [pq.read_table(r / "descent_landmarks.parquet").to_pydict() for r in runs]
    ts_dir = next((d / "camp" / "work" / "truth_cache").glob("*/manifest.json")).parent
    return d, filt, lms, ts_dir


def _rows(t: dict):
    return [{k: t[k][i] for k in t} for i in range(len(t["run"]))]


def _project(p_body, pos, R_body_from_cam, cam):
    R = R_body_from_cam.T
    rvec, _ = cv2.Rodrigues(R)
    K = np.array([[cam["fx"], 0, cam["cx"]], [0, cam["fy"], cam["cy"]], [0, 0, 1.0]])
    out, _ = cv2.projectPoints(np.asarray(p_body, float).reshape(-1, 1, 3), rvec, -R @ pos, K, None)
    return out.reshape(-1, 2)


def test_truth_trajectory_is_the_rendered_one(campaign):
    from renderlab.files.truthset import TruthSet
    from renderlab.scenario import load_scenario
    from renderlab.studies.descent_navigation.run import section
    from renderlab.studies.descent_navigation.truth import true_descent

    d, _, _, ts_dir = campaign
    sc, _ = load_scenario(d / "tiny.toml")
    ts = TruthSet.open(ts_dir)
    tr = true_descent(ts, sc, section(sc))
    t = np.array([r["time_s"] for r in ts.frames])
    assert np.abs(tr.position(t) - np.array([r["pose"]["position_m"] for r in ts.frames])).max() < 1e-6


def test_methods_get_their_apriori_pose_and_search_distance_from_the_filter(campaign):
    from renderlab.worlds.ev5.catalog import read_catalog

    d, filt, lms, ts_dir = campaign
    man = json.loads((ts_dir / "manifest.json").read_text())
    centres = {m.landmark_id: m.center_m for m in read_catalog(ts_dir)}
    cam = man["frames"][0]["camera"]
    sig_st = math.radians(10.0 / 3600.0)
    checked = 0
    for f, lm in zip(filt, lms):
        pri = {(r["method"], r["frame"]): r for r in _rows(f)}
        for r in _rows(lm):
            p = pri[(r["method"], r["frame"])]
            pos = np.array([p[f"apriori_pos_{a}_m"] for a in "xyz"])
            R = Rotation.from_quat([p[f"star_quat_body_from_cam_{a}"] for a in "xyzw"]).as_matrix()
            s, l = _project(centres[r["item"]], pos, R, cam)[0]
            assert abs(s - r["pred_s"]) < 1e-6 and abs(l - r["pred_l"]) < 1e-6
            if r["frame"] == 0:       # a-priori covariance = P0: 1 m per axis, star tracker 10 arcsec
                c = centres[r["item"]]
                Jt = np.column_stack([(_project(c, pos + h, R, cam) - _project(c, pos - h, R, cam))[0] / 2e-4
                                      for h in np.eye(3) * 1e-4])
                Jr = np.column_stack([(_project(c, pos, R @ Rotation.from_rotvec(h).as_matrix(), cam)
                                       - _project(c, pos, R @ Rotation.from_rotvec(-h).as_matrix(), cam))[0] / 2e-7
                                      for h in np.eye(3) * 1e-7])
                cov = Jt @ Jt.T + sig_st**2 * Jr @ Jr.T
                want = min(max(math.ceil(3 * math.sqrt(np.linalg.eigvalsh(cov)[-1])), 2), 32)
                assert r["search_px"] == want
            checked += 1
    assert checked > 20


def test_filter_rows_are_the_estimate_against_the_rendered_truth(campaign):
    d, filt, _, ts_dir = campaign
    man = json.loads((ts_dir / "manifest.json").read_text())
    R_site = np.array(json.loads((ts_dir / "site.json").read_text())["R_body_from_site"])
    for f in filt:
        rows = _rows(f)
        assert {r["method"] for r in rows} == {"retina", "spc"}
        for r in rows:
            if r["frame"] < 0:
                assert r["reason"] == "prior"
                continue
            true = np.array(man["frames"][r["frame"]]["pose"]["position_m"])
            est = np.array([r[f"est_pos_{a}_m"] for a in "xyz"])
            assert np.allclose(R_site.T @ (est - true), [r["err_e_m"], r["err_n_m"], r["err_u_m"]], atol=1e-6)
            assert r["dof"] == 2 * r["n_kept"] and r["nees"] >= 0
            assert r["reason"] == ("ok" if r["n_kept"] else "all_gated")
        last = [r for r in rows if r["frame"] == 2]
        assert all(math.hypot(r["err_e_m"], r["err_n_m"], r["err_u_m"]) < 1.0 for r in last)


def test_report_regenerates_csvs_and_figures(campaign):
    d, *_ = campaign
    rep = d / "report"
    rows = list(csv.DictReader(open(rep / "descent_summary.csv")))
    assert {r["method"] for r in rows} == {"retina", "spc"} and all(int(r["n_runs"]) == RUNS for r in rows)
    for stem in ("descent_position_error", "descent_velocity_error", "descent_consistency"):
        assert (rep / f"{stem}.png").stat().st_size > 1000 and not (rep / f"{stem}.svg").exists()
    assert "Descent navigation" in (rep / "index.html").read_text()


def test_study_refuses_an_unknown_method_before_running(tmp_path, capsys):
    (tmp_path / "bad.toml").write_text(TINY.replace('methods = ["retina", "spc"]', 'methods = ["retna"]'))
    assert main(["campaign", str(tmp_path / "bad.toml"), "--runs", "1", "--out", str(tmp_path / "c"),
                 "--workers", "0", "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "retna" in err and len(err.splitlines()) == 1 and not (tmp_path / "c").exists()


MAPS = TINY.replace('max_landmarks = 6\n', 'max_landmarks = 6\nmap_realisation = "per_run"\nmap_states = "estimate"\n'
                    'map_keep_updates = 1\nlandmark_error_by_method = {retina = [[0.2, 0.1, 0.02]]}\n')


@pytest.fixture(scope="module")
def campaign_maps(tmp_path_factory):
    d = tmp_path_factory.mktemp("dnav_maps")
    (d / "tiny.toml").write_text(MAPS)
    assert main(["campaign", str(d / "tiny.toml"), "--runs", str(RUNS), "--out", str(d / "camp"), "--workers", "0",
                 "--quiet"]) == 0
    assert main(["report", str(d / "camp"), "--out", str(d / "report")]) == 0
    runs = sorted((d / "camp" / "runs").iterdir())
    filt = [pq.read_table(r / "descent_filter.parquet").to_pydict() for r in runs]
    lms = [pq.read_table(r / "descent_landmarks.parquet").to_pydict() for r in runs]
    ts_dir = next((d / "camp" / "work" / "truth_cache").glob("*/manifest.json")).parent
    return d, filt, lms, ts_dir


def test_map_states_are_the_landmarks_kept_in_the_last_images(campaign_maps):
    """keep_updates = 1: after each image the filter holds the map errors of exactly the landmarks it kept in that
    image (recounted from the landmark table), and the landmark rows carry their GSD and maplet spacing."""
    _, filt, lms, _ = campaign_maps
    for f, lm in zip(filt, lms):
        kept = {}
        for m, k, item, keep in zip(lm["method"], lm["frame"], lm["item"], lm["kept"]):
            if keep:
                kept.setdefault((m, k), set()).add(item)
        for r in _rows(f):
            if r["frame"] >= 0 and r["n_results"] > 0:
                assert r["n_map_states"] == len(kept.get((r["method"], r["frame"]), ())), r
        assert all(g > 0 for g in lm["gsd_m"]) and set(lm["spacing_m"]) <= {0.2, 0.1}


def test_per_run_maps_are_fresh_draws_of_the_declared_mapping_error(campaign_maps):
    """The per-run catalogue (renderlab.campaign.maplets) against the truth set's: same ids, centres, frames and
    spacing; heights differ by two independent draws of the world's mapping error (rms √2 · 3 cm, the EV5 default),
    the relative albedo by two draws of its 2 % error; two generators give two different maps."""
    from renderlab.campaign.maplets import respaced_maplets
    from renderlab.scenario import load_scenario
    from renderlab.worlds.ev5.catalog import read_catalog

    d, _, _, ts_dir = campaign_maps
    sc, _ = load_scenario(d / "tiny.toml")
    cat = read_catalog(ts_dir)
    a = respaced_maplets(cat, sc.world, d, 1.0, np.random.default_rng(1))
    b = respaced_maplets(cat, sc.world, d, 1.0, np.random.default_rng(2))
    dh = np.concatenate([(m.heights_m - c.heights_m).ravel() for m, c in zip(a, cat)])
    da = np.concatenate([(m.albedo / c.albedo).ravel() - 1 for m, c in zip(a, cat)])
    assert [m.landmark_id for m in a] == [c.landmark_id for c in cat]
    assert all(np.allclose(m.center_m, c.center_m) and m.spacing_m == c.spacing_m for m, c in zip(a, cat))
    assert np.sqrt(np.mean(dh**2)) == pytest.approx(np.sqrt(2) * 0.03, rel=0.2)
    assert np.sqrt(np.mean(da**2)) == pytest.approx(np.sqrt(2) * 0.02, rel=0.2)
    assert not np.allclose(a[0].heights_m, b[0].heights_m)


def test_report_of_a_map_state_campaign_has_the_independence_scores(campaign_maps):
    d, *_ = campaign_maps
    rep = d / "report"
    rows = list(csv.DictReader(open(rep / "descent_independence.csv")))
    assert {r["method"] for r in rows} == {"retina", "spc"} and {int(r["frame"]) for r in rows} == {0, 1, 2}
    for r in rows:
        rho = float(r["rho_state"])
        assert 0.0 <= rho <= 1.0
        n = int(r["n_runs"])
        assert float(r["n_eff"]) == pytest.approx(n / (1 + (n - 1) * rho**2), rel=1e-5)
    assert {r["method"] for r in csv.DictReader(open(rep / "descent_bands.csv"))} == {"retina", "spc"}
    assert (rep / "descent_independence.png").stat().st_size > 1000 and not (rep / "descent_independence.svg").exists()
