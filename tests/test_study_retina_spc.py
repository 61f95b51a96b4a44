"""Study ``retina_vs_spc`` end to end: ``renderlab campaign`` → ``renderlab report`` on a tiny EV5 descent.

A real Mitsuba render of a tiny EV5 site (128², 2 frames, 2 spp) is made once through the truth cache and
measured by Retina and SPC in 3 runs that differ in the a-priori pose, camera/Sun knowledge, maplet spacing
and sensor noise. Oracles: OpenCV ``projectPoints`` of the landmark centre with the believed camera (nominal
camera + the run's stored focal/principal-point/k1 offsets) and the a-priori pose (the row's stored draw)
must give each row's prediction; truth columns must be the truth set's ``landmark_truth`` table.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from tiny_ev5 import TINY_EV5_WORLD

from renderlab.cli import main

TINY = 'name = "ev5_tiny_campaign"\n' + TINY_EV5_WORLD + """[trajectory]
kind = "ev5_descent"
altitudes_m = [65.0, 45.0]
[camera]
width = 128
height = 128
fx = 610.0
fy = 610.0
cx = 63.5
cy = 63.5
[render]
spp = 2
seed = 3
near_clip_m = 0.01
[perturbations]
apriori_position_sigma_m = [0.2, 0.2, 0.2]
apriori_attitude_sigma_deg = 0.05
focal_length_sigma_frac = 0.002
principal_point_sigma_px = 0.3
distortion_sigma = {k1 = 0.02}
maplet_spacing_sigma_frac = 0.05
sun_direction_sigma_deg = 1.0
[campaign]
seed = 11
"""
RUNS = 3


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    d = tmp_path_factory.mktemp("rvs")
    scen = d / "tiny.toml"
    scen.write_text(TINY)
    assert main(["campaign", str(scen), "--runs", str(RUNS), "--out", str(d / "camp"), "--workers", "0", "--quiet"]) == 0
    assert main(["report", str(d / "camp"), "--out", str(d / "report")]) == 0
    runs = sorted((d / "camp" / "runs").iterdir())
    meas = [pq.read_table(r / "measurements.parquet").to_pydict() for r in runs]
    pert = [pq.read_table(r / "perturbations.parquet").to_pydict() for r in runs]
    return d, meas, pert


def _truth_set(d: Path):
    from renderlab.files.truthset import TruthSet

    sets = [p for p in (d / "camp" / "work" / "truth_cache").iterdir() if (p / "manifest.json").is_file()]
    assert len(sets) == 1, "one truth render serves every run"
    return TruthSet.open(sets[0])


def test_both_methods_same_frames_same_apriori_and_truth_from_truth_table(campaign):
    d, meas, _ = campaign
    assert len(meas) == RUNS
    truth = _truth_set(d).read_table("landmark_truth").to_pydict()
    tmap = {(f, i): (s, l, g) for f, i, s, l, g in zip(truth["frame"], truth["landmark_id"], truth["s"], truth["l"],
                                                       truth["gsd_ratio"])}
    for m in meas:
        rows = {}
        for k, meth in enumerate(m["method"]):
            rows.setdefault(meth, {})[(m["frame"][k], m["item"][k])] = k
        # the default methods: the paper's Retina, Retina with the refined peak step, SPC, the baseline plug-in
        assert set(rows) == {"retina", "retina_refined", "spc", "ncc_baseline"}
        assert rows["retina"].keys() == rows["retina_refined"].keys() == rows["spc"].keys() == rows["ncc_baseline"].keys()
        assert len(rows["retina"]) > 10
        for key, kr in rows["retina"].items():
            for other in ("retina_refined", "spc", "ncc_baseline"):
                ks = rows[other][key]
                for c in ("apriori_dpos_x_m", "apriori_dpos_z_m", "apriori_drot_y_rad", "pred_s", "pred_l"):
                    assert m[c][kr] == pytest.approx(m[c][ks], abs=1e-9), c
                assert m["photometry"][kr] == m["photometry"][ks]  # the same ground photometric knowledge
            assert (m["truth_s"][kr], m["truth_l"][kr]) == pytest.approx(tmap[key][:2], abs=1e-9)
        for c in ("range_m", "albedo_contrast", "phase_deg", "gsd_ratio", "crlb_s", "crlb_l"):
            assert np.all(np.isfinite(m[c])), c
        assert set(m["crlb_bound"]) == {"continuous"}  # the bound of the continuous truth (renderlab.campaign.crlb)
        assert 40 < min(m["range_m"]) and max(m["range_m"]) < 80  # frames at 65 and 45 m altitude
    # different runs draw different a-priori poses
    assert meas[0]["apriori_dpos_x_m"][0] != meas[1]["apriori_dpos_x_m"][0]


def test_prediction_uses_believed_camera_and_apriori_pose_opencv(campaign):
    import cv2
    from scipy.spatial.transform import Rotation

    from renderlab.worlds.ev5.catalog import read_catalog

    d, meas, pert = campaign
    ts = _truth_set(d)
    centres = {int(mp.landmark_id): mp.center_m for mp in read_catalog(ts.path)}
    checked = 0
    for m, p in zip(meas, pert):
        for k in range(0, len(m["frame"]), 7):
            rec = ts.frames[m["frame"][k]]
            cam = rec["camera"]
            R_true = Rotation.from_quat(rec["pose"]["quat_render_from_cam_xyzw"])
            R_ap = R_true * Rotation.from_rotvec([m[f"apriori_drot_{a}_rad"][k] for a in "xyz"])
            p_ap = np.asarray(rec["pose"]["position_m"]) + [m[f"apriori_dpos_{a}_m"][k] for a in "xyz"]
            p_cam = R_ap.inv().apply(centres[m["item"][k]] - p_ap)
            f = p["focal_scale"][0]
            K = np.array([[cam["fx"] * f, 0, cam["cx"] + p["dpp_s"][0]], [0, cam["fy"] * f, cam["cy"] + p["dpp_l"][0]],
                          [0, 0, 1]])
            uv, _ = cv2.projectPoints(p_cam.reshape(1, 3), np.zeros(3), np.zeros(3), K,
                                      np.array([p["ddist_k1"][0], 0, 0, 0, 0]))
            assert (m["pred_s"][k], m["pred_l"][k]) == pytest.approx(tuple(uv.ravel()), abs=1e-6)
            checked += 1
    assert checked >= 6
    assert len({p["focal_scale"][0] for p in pert}) == RUNS  # the knowledge errors differ per run


def test_spacing_knowledge_scales_gsd_ratio_and_noise_is_redrawn(campaign):
    from renderlab.campaign.perturb import PerturbationDraw
    from renderlab.scenario import load_scenario
    from renderlab.sensor.model import SensorOptions, expected_dn
    from renderlab.studies.retina_vs_spc.run import BelievedTruthSet

    d, meas, pert = campaign
    ts = _truth_set(d)
    truth = ts.read_table("landmark_truth").to_pydict()
    g0 = {(f, i): g for f, i, g in zip(truth["frame"], truth["landmark_id"], truth["gsd_ratio"])}
    for m, p in zip(meas, pert):
        assert p["spacing_scale"][0] != 1.0
        k = 0
        assert m["gsd_ratio"][k] * p["spacing_scale"][0] == pytest.approx(g0[(m["frame"][k], m["item"][k])], rel=1e-9)
    opts = SensorOptions(**load_scenario(d / "tiny.toml")[0].sensor.options_dict())
    a, b = BelievedTruthSet(ts, PerturbationDraw(), opts, [1, 2]), BelievedTruthSet(ts, PerturbationDraw(), opts, [1, 2])
    c = BelievedTruthSet(ts, PerturbationDraw(), opts, [3, 4])
    dn_a, dn_c = a.load(0).dn.astype(float), c.load(0).dn.astype(float)
    assert np.array_equal(dn_a, b.load(0).dn) and not np.array_equal(dn_a, dn_c)  # seeded, per run
    mean = expected_dn(np.asarray(ts.load(0).radiance, float), a.sensor_options(0))
    assert abs(np.mean(dn_a - mean)) < 0.2  # unbiased re-exposure
    assert np.mean(np.abs(dn_a - ts.load(0).dn)) > 0.5  # a new noise realisation, not the cached one


def test_report_has_every_method_with_cluster_intervals_and_the_declared_subset(campaign):
    from renderlab.report.landmark_stats import cluster_ids
    from renderlab.stats.bootstrap import cluster_bootstrap

    d, meas, _ = campaign
    rows = list(csv.DictReader((d / "report" / "summary.csv").open()))
    got = {(r["subset"], r["method"], r["axis"]) for r in rows}
    assert {(sub, m, a) for sub in ("all", "well_measured") for m in ("retina", "retina_refined", "spc", "ncc_baseline")
            for a in "sl"} <= got
    for r in rows:
        if int(r["n_result"]) >= 2 and int(r["n_clusters"]) >= 2:
            assert float(r["bias_px_lo"]) <= float(r["bias_px"]) <= float(r["bias_px_hi"])
    # the 'all' retina line bias interval is the cluster bootstrap over landmark-frames of the raw rows
    import pyarrow as pa

    t = pa.concat_tables([pa.table(m) for m in meas], promote_options="permissive")
    sel = (np.array(t.column("method").to_pylist()) == "retina") & np.array(t.column("has_result").to_pylist(), bool)
    e = np.array(t.column("err_l").to_pylist(), float)
    iv = cluster_bootstrap(e[sel], cluster_ids(t)[sel], "mean", n_boot=2000, rng=0)
    r = next(r for r in rows if (r["subset"], r["method"], r["axis"]) == ("all", "retina", "l"))
    assert float(r["bias_px_lo"]) == pytest.approx(iv.lo, rel=1e-5) and float(r["bias_px_hi"]) == pytest.approx(iv.hi, rel=1e-5)
    html = (d / "report" / "index.html").read_text()
    assert all(m in html for m in ("retina", "spc", "ncc_baseline")) and "Well-measured subset" in html


def test_published_tables_hold_what_the_report_reads_and_give_the_same_report(campaign, tmp_path):
    """Publishing applies the study's ``publish_tables``: ``measurements`` keeps the columns the report reads, the full
    table is recorded in ``raw_tables.json``, and the report of the reduced tables equals the campaign's (every CSV)."""
    import json

    from renderlab.campaign.publish import publish_campaign
    from renderlab.studies.retina_vs_spc.report import PUBLISHED_COLUMNS

    d, meas, _ = campaign
    out = publish_campaign(d / "camp", tmp_path / "pub")
    t = pq.read_table(out / "tables" / "measurements.parquet")
    assert set(t.column_names) == set(PUBLISHED_COLUMNS) and t.num_rows == sum(len(m["run"]) for m in meas)
    raw = json.loads((out / "tables" / "raw_tables.json").read_text())["tables"]
    assert set(raw) == {"measurements"} and {"meas_s", "score", "t_ms"} <= set(raw["measurements"]["columns"])
    assert main(["report", str(out), "--out", str(tmp_path / "rep"), "--tables-only"]) == 0
    names = sorted(p.name for p in (d / "report").glob("*.csv"))
    assert "summary.csv" in names and "measurements_breakdown.csv" in names
    for name in names:
        assert (tmp_path / "rep" / name).read_text() == (d / "report" / name).read_text(), name


class ShiftedNcc:
    """A user's own method typed on the command line (not installed, no entry point): the NCC baseline under
    another name."""

    name = "my_ncc"

    def __init__(self, options):
        from renderlab_ncc_baseline.method import NccBaseline

        self._impl = NccBaseline(options)

    def measure_frame(self, frame):
        return self._impl.measure_frame(frame)


def test_campaign_with_a_plugin_typed_on_the_command_line(tmp_path, capsys):
    """``--plugin module:attr`` registers a method for one campaign; the scenario names it by its name only; a
    scenario naming a module is refused before anything is created."""
    scen = tmp_path / "tiny.toml"
    scen.write_text(TINY + '\n[retina_vs_spc]\nmethods = ["retina", "my_ncc"]\n')
    out = tmp_path / "c"
    argv = ["campaign", str(scen), "--runs", "1", "--out", str(out), "--workers", "0", "--quiet"]
    assert main(argv) == 2 and "unknown landmark method 'my_ncc'" in capsys.readouterr().err
    assert not out.exists()
    assert main([*argv, "--plugin", "test_study_retina_spc:ShiftedNcc"]) == 0
    import pyarrow.parquet as pq

    t = pq.read_table(out / "runs" / "000000" / "measurements.parquet").to_pydict()
    assert set(t["method"]) == {"retina", "my_ncc"} and sum(t["has_result"]) > 10
    bad = tmp_path / "bad.toml"
    bad.write_text(TINY + '\n[retina_vs_spc]\nmethods = ["test_study_retina_spc:ShiftedNcc"]\n')
    capsys.readouterr()
    assert main(["campaign", str(bad), "--runs", "1", "--out", str(tmp_path / "c2"), "--workers", "0"]) == 2
    err = capsys.readouterr().err
    assert "retina_vs_spc.methods" in err and err.count("\n") == 1 and not (tmp_path / "c2").exists()
