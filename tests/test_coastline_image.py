"""Image-in-the-loop coastline navigation on real Mitsuba renders of GSHHG coast (Portugal/Spain, 128 px, 30° FOV).

Oracles: ``coastline_truth.parquet`` (full-resolution GSHHG projected with the true camera, independent of the
extraction) for the edge points; the true camera pose for the matcher (the database projected with the true pose
is where the observed points must lie, whatever a-priori offset the matcher started from). The renders go through
the campaign's truth cache, so the study test at the end reuses them instead of rendering again.
"""

from __future__ import annotations

import json

import earth_fixtures
import numpy as np
import pyarrow.parquet as pq
import pytest
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from estimators.coastline.extract import ExtractOptions, extract_coastline
from estimators.coastline.match import MatchOptions, match_coastline

gshhg = earth_fixtures.gshhg

SMALL = ["camera.width=128", "camera.height=128", "trajectory.frames=2", "trajectory.start_s=1230"]


def _truthset(repo, cache, *overrides):
    from renderlab.campaign.cache import cached_truthset
    from renderlab.files.truthset import TruthSet
    from renderlab.scenario import load_scenario, scenario_from_dict
    from renderlab.studies.coastline_ekf.image import render_scenario_dict

    sc, base = load_scenario(repo / "scenes/coastline_image.toml", [*SMALL, *overrides])
    path, _ = cached_truthset(scenario_from_dict(render_scenario_dict(sc)), base, cache)
    return sc, base, TruthSet.open(path)


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("coastline_truth_cache")


@pytest.fixture(scope="module")
def clear(repo, cache, gshhg):
    return _truthset(repo, cache, "world.cloud_cover=0.0")


@pytest.fixture(scope="module")
def cloudy(repo, cache, gshhg):
    return _truthset(repo, cache)  # the scene's 30 % cloud cover


def _truth_points(ts, k):
    t = ts.read_table("coastline_truth")
    sel = t["frame"].to_numpy() == k
    return np.stack([t["s"].to_numpy()[sel], t["l"].to_numpy()[sel]], -1)


def _bias(ts, k):
    return float(ts.frames[k]["sensor"]["bias_dn"])


def test_extraction_on_clear_render_matches_gshhg(clear):
    _, _, ts = clear
    for k in range(len(ts)):
        fr = ts.load(k)
        ex = extract_coastline(fr.dn.astype(float) - _bias(ts, k))
        truth = _truth_points(ts, k)
        assert len(truth) > 300 and len(ex.points) > 100, "the frame must show coastline"
        assert ex.level_cloud is None and ex.n_cloud_edges == 0 and np.all(ex.clean)
        d, _ = cKDTree(truth).query(ex.points)
        print(f"frame {k}: {len(d)} edge points, median {np.median(d):.3f} px, p95 {np.percentile(d, 95):.3f} px")
        assert np.median(d) <= 0.5 and np.percentile(d, 95) <= 1.0          # issue: median ≤ 1 px
        inner = truth[np.all((truth > 4) & (truth < 123), axis=1)]
        d2, _ = cKDTree(ex.points).query(inner)
        # the rest of the true coast is islets/inlets below the 4 km pixel, removed by the morphology step
        assert np.mean(d2 < 1.5) > 0.4


def test_cloud_edges_rejected(cloudy):
    _, _, ts = cloudy
    naive = ExtractOptions(cloud_ratio=1e9, max_land_water_ratio=1e9)     # two classes, no cloud logic
    for k in range(len(ts)):
        fr = ts.load(k)
        img = fr.dn.astype(float) - _bias(ts, k)
        truth = cKDTree(_truth_points(ts, k))
        ex, bad = extract_coastline(img), extract_coastline(img, naive)
        assert ex.level_cloud is not None and ex.n_cloud_edges > 100, "the frame must contain clouds"
        d_clean, _ = truth.query(ex.points[ex.clean])
        d_naive, _ = truth.query(bad.points)
        print(f"frame {k}: clean {len(d_clean)} (median {np.median(d_clean):.3f} px, max {d_clean.max():.2f}), "
              f"flagged {(~ex.clean).sum()}, cloud edges rejected {ex.n_cloud_edges}; "
              f"naive: {np.sum(d_naive > 3)} of {len(d_naive)} edges > 3 px off")
        assert len(d_clean) > 50 and np.median(d_clean) <= 0.5 and d_clean.max() <= 3.0
        # the frame is a real test: without the cloud logic, cloud edges (>3 px from any coast) appear
        # (measured: 535 and 145 of them in the two frames)
        assert np.sum(d_naive > 3) > 50


def test_matching_with_known_apriori_offset(clear, gshhg):
    """A-priori attitude off by (7, −5) px and position by 2 km: the registration finds the offset and the
    observed points lie on the database projected with the *true* pose."""
    import shapely

    from renderlab.geometry.camera import CameraModel
    from renderlab.worlds.earth.coast_db import CoastDBOptions, build_coast_db

    _, _, ts = clear
    bounds = json.loads((ts.path / "coast_db.json").read_text())["region_bounds_lonlat_deg"]
    db = build_coast_db(gshhg, shapely.box(*bounds), CoastDBOptions(150.0, 0.0, 100e3, 0))
    P = np.stack([db["x_ecef_m"], db["y_ecef_m"], db["z_ecef_m"]], -1)
    for k in range(len(ts)):
        fr = ts.load(k)
        sc = fr.meta["spacecraft"]
        cam = CameraModel.from_dict(fr.meta["camera"])
        R = Rotation.from_quat(sc["quat_ecef_from_cam_xyzw"]).as_matrix()
        r = np.asarray(sc["r_ecef_m"])
        dR = Rotation.from_rotvec([7.0 / cam.fy, -5.0 / cam.fx, 0.0]).as_matrix()
        ex = extract_coastline(fr.dn.astype(float) - _bias(ts, k))
        mt = match_coastline(ex.points[ex.clean], P, r + np.array([1500.0, -1000.0, 700.0]), (R @ dR).T, cam,
                             MatchOptions(points_per_image=64))
        assert mt.ok and len(mt.db_index) >= 5
        true_sl = cam.project((P[mt.db_index] - r) @ R)
        expected_shift = np.median(true_sl - mt.pred_sl, axis=0)     # what the a-priori error does in the image
        err = np.linalg.norm(mt.obs_sl - true_sl, axis=1)
        print(f"frame {k}: shift {mt.shift_px} vs {expected_shift}, {len(err)} matches, obs−true median "
              f"{np.median(err):.3f} px, max {err.max():.3f} px")
        assert np.hypot(*(expected_shift)) > 7.0
        assert np.all(np.abs(mt.shift_px - expected_shift) < 0.5)
        assert np.median(err) < 0.5 and err.max() < 2.0
        los_true = (P[mt.db_index] - r) @ R
        los_true /= np.linalg.norm(los_true, axis=1, keepdims=True)
        ang = np.arccos(np.clip(np.einsum("ij,ij->i", los_true, mt.los_cam), -1, 1))
        assert np.median(ang) < 0.5 / cam.fx                            # LOS within half a pixel (rad)


def test_image_study_through_campaign_engine(repo, clear, cache, tmp_path):
    """Two seeded runs of the image-in-the-loop study on the cached clear render: tables, replay, report."""
    from renderlab.campaign.plan import make_plan, run_seed_sequence
    from renderlab.campaign.runner import run_campaign
    from renderlab.report.campaign_report import make_report
    from renderlab.studies.coastline_ekf.study import run

    sc, base, _ = clear
    from renderlab.campaign import store

    out = tmp_path / "camp"
    plan = make_plan(sc, base, 2)
    store.open_campaign(out, plan, resume=False)
    (out / "work").mkdir(exist_ok=True)
    (out / "work" / "truth_cache").symlink_to(cache, target_is_directory=True)   # reuse the fixture's render
    res = run_campaign(plan, out, progress=False, resume=True)
    assert res.executed == 2 and not res.failed
    filt = pq.read_table(out / "runs/000001/coastline_filter.parquet")
    frames = pq.read_table(out / "runs/000001/coastline_frames.parquet")
    assert filt.num_rows == 3 and frames.num_rows == 2
    assert np.all(frames["n_matched"].to_numpy() >= 5)
    assert np.all(frames["los_err_px_median"].to_numpy() < 1.0)
    sig0 = filt["sig_i_m"].to_numpy()
    assert sig0[-1] < sig0[0]                                             # the images carried information
    again = run(sc, base, 1, run_seed_sequence(sc.campaign.seed, 1), out / "work")
    rep = again["coastline_filter"]                                      # run 1 replays alone bit-identically
    assert rep.column_names == filt.drop(["campaign"]).column_names
    for name in rep.column_names:
        np.testing.assert_array_equal(rep[name].to_numpy(), filt[name].to_numpy())
    # coastline.map_error_in_filter: the filter adds σ_map/h to its shared per-image LOS term → a larger σ
    sc_q = sc.model_copy(update={"coastline": sc.coastline.model_copy(update={"map_error_in_filter": True})})
    q = run(sc_q, base, 1, run_seed_sequence(sc.campaign.seed, 1), out / "work")["coastline_filter"]
    assert np.all(q["sig_i_m"].to_numpy()[1:] > filt["sig_i_m"].to_numpy()[1:])
    page = make_report(out, tmp_path / "report")
    assert (tmp_path / "report" / "coastline_filter_coastline_errors.png").is_file()
    text = page.read_text()
    assert "Straub" in text and "Filter: coastline_filter" not in text     # reported once, by the study
