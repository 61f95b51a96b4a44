"""Campaign engine: plans, seeds, perturbations, the truth cache, failing runs, malformed plans.

Tiny real renders of ``scenes/analytic_sphere_box.toml`` (64×48, 4 spp, 1 frame) with the in-process
executor. The truth columns are checked against OpenCV's ``projectPoints`` with the manifest's pose;
a run replayed alone gives the campaign's tables; the cache serves a re-run without new renders.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from campaign_fixtures import SCENE, TINY, tables_equal

from renderlab.campaign import store
from renderlab.campaign.executors import InProcessExecutor, execute_run
from renderlab.campaign.perturb import draw_perturbation, perturb_camera
from renderlab.campaign.plan import make_plan, run_seed_sequence
from renderlab.campaign.runner import run_campaign
from renderlab.cli import main
from renderlab.errors import UserError
from renderlab.scenario import load_scenario
from renderlab.scenario.campaign import PerturbationConfig

REPO = Path(__file__).resolve().parents[1]


def flaky_study(scenario, base_dir, run_index, seed_sequence, workdir):
    """A study that fails on odd runs (used to check that the campaign goes on)."""
    import pyarrow as pa

    if run_index % 2:
        raise RuntimeError(f"deliberate failure of run {run_index}")
    return {"values": pa.table({"x": [float(np.random.default_rng(seed_sequence).normal())]})}


def always_fails(scenario, base_dir, run_index, seed_sequence, workdir):
    raise UserError("target not in view")


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    d = tmp_path_factory.mktemp("engine")
    sc, base = load_scenario(SCENE, TINY)
    plan = make_plan(sc, base, runs=3, seed=5)
    res = run_campaign(plan, d / "c", progress=False)
    return plan, d, res


def test_campaign_runs_and_truth_matches_opencv(campaign):
    import cv2
    from scipy.spatial.transform import Rotation

    from renderlab.files.truthset import TruthSet

    plan, d, res = campaign
    assert (res.executed, res.skipped, res.failed) == (3, 0, [])
    t = store.load_tables(d / "c")["measurements"]
    assert sorted(set(t.column("run").to_pylist())) == [0, 1, 2]
    assert set(t.column("method").to_pylist()) == {"centroid", "ellipse"}
    err = np.array(t.column("err_s").to_pylist()) - (np.array(t.column("meas_s").to_pylist())
                                                      - np.array(t.column("truth_s").to_pylist()))
    assert np.nanmax(np.abs(err)) == 0.0
    sphere = np.array(plan.scenario.world.bodies[1].center_m)
    caches = sorted((d / "c" / "work" / "truth_cache").iterdir())
    assert len(caches) == 3  # one render per run (1 frame), cached per (scene, pose)
    truth = {(r["truth_s"], r["truth_l"]) for r in t.to_pylist()}
    for path in caches:
        meta = TruthSet.open(path).frames[0]
        R = Rotation.from_quat(meta["pose"]["quat_render_from_cam_xyzw"]).as_matrix()
        rvec, _ = cv2.Rodrigues(R.T)
        tvec = -R.T @ np.array(meta["pose"]["position_m"])
        c = meta["camera"]
        K = np.array([[c["fx"], 0, c["cx"]], [0, c["fy"], c["cy"]], [0, 0, 1.0]])
        sl, _ = cv2.projectPoints(sphere[None], rvec, tvec, K, None)
        assert min(np.hypot(*(np.array(p) - sl.ravel())) for p in truth) < 1e-9
    ok = t.filter(np.array(t.column("has_result").to_pylist(), bool))
    assert ok.num_rows >= 3
    assert np.all(np.abs(ok.column("err_s").to_numpy()) < 4) and np.all(np.abs(ok.column("err_l").to_numpy()) < 4)


def test_replay_one_run_alone_and_cache_hit(campaign, tmp_path):
    plan, d, _ = campaign
    n_cache = len(list((d / "c" / "work" / "truth_cache").iterdir()))
    task = plan.tasks(d / "c", [1])[0]
    assert task.seed_sequence().generate_state(4).tolist() == \
        np.random.SeedSequence(5).spawn(3)[1].generate_state(4).tolist()
    # same campaign folder (cache hit) into a copy of the run folder
    orig = {n: pq.read_table(store.run_dir(d / "c", 1) / f"{n}.parquet") for n in ("measurements", "perturbations")}
    st = execute_run(task)
    assert st["status"] == "ok"
    assert len(list((d / "c" / "work" / "truth_cache").iterdir())) == n_cache  # nothing re-rendered
    for n, tab in orig.items():
        assert tables_equal(tab, pq.read_table(store.run_dir(d / "c", 1) / f"{n}.parquet"))
    # a fresh folder renders again and gets the same tables
    store.open_campaign(tmp_path / "solo", plan, resume=False)
    execute_run(plan.tasks(tmp_path / "solo", [1])[0])
    for n, tab in orig.items():
        assert tables_equal(tab, pq.read_table(store.run_dir(tmp_path / "solo", 1) / f"{n}.parquet"))


def test_perturbation_draws():
    cov = np.array([[0.04, 0.01, 0.0], [0.01, 0.09, 0.0], [0.0, 0.0, 0.01]])
    cfg = PerturbationConfig(position_cov_m2=cov.tolist(), sun_direction_sigma_deg=1.0, focal_length_sigma_frac=0.01)
    draws = [draw_perturbation(cfg, run_seed_sequence(1, i)) for i in range(3000)]
    dp = np.array([x.dposition_m for x in draws])
    assert np.cov(dp.T) == pytest.approx(cov, abs=0.006)
    assert np.std([x.focal_scale for x in draws]) == pytest.approx(0.01, rel=0.06)
    ang = np.degrees([np.linalg.norm(x.sun_rotvec_rad) for x in draws])
    assert np.sqrt(np.mean(ang**2)) == pytest.approx(np.sqrt(3), rel=0.06)  # 3 axes of 1 deg
    # independent streams: switching another dispersion on leaves the position draws unchanged
    cfg2 = PerturbationConfig(position_cov_m2=cov.tolist(), principal_point_sigma_px=2.0)
    assert np.array_equal(draw_perturbation(cfg2, run_seed_sequence(1, 7)).dposition_m, dp[7])
    nominal = draw_perturbation(PerturbationConfig(), run_seed_sequence(1, 0))
    assert nominal.focal_scale == 1.0 and not nominal.dposition_m.any() and not nominal.sun_rotvec_rad.any()
    cam = {"width": 10, "height": 10, "fx": 100.0, "fy": 90.0, "cx": 4.5, "cy": 4.5, "model": "pinhole"}
    d = draw_perturbation(PerturbationConfig(focal_length_sigma_frac=0.1, principal_point_sigma_px=1,
                                             distortion_sigma={"k1": 0.01}), run_seed_sequence(2, 0))
    out = perturb_camera(cam, d)
    assert (out["fx"] / 100.0, out["fy"] / 90.0) == pytest.approx((d.focal_scale, d.focal_scale), rel=1e-15)
    assert (out["cx"] - 4.5, out["cy"] - 4.5) == pytest.approx(tuple(d.dprincipal_point_px), abs=1e-14)
    assert out["model"] == "brown" and out["distortion"] == {"k1": d.ddistortion["k1"]}


def _register(name, fn):
    from renderlab import plugins
    from renderlab.contracts.study import Study

    plugins.studies.register(name, Study(name=name, run=fn, worlds=("analytic",)))


def test_failing_runs_are_recorded_and_the_campaign_goes_on(tmp_path):
    from renderlab import plugins

    sc, base = load_scenario(SCENE, TINY)
    _register("flaky", flaky_study)
    _register("always_fails", always_fails)
    with pytest.raises(UserError, match="unknown study 'test_campaign_engine:flaky_study'"):
        make_plan(sc, base, runs=4, seed=0, study="test_campaign_engine:flaky_study")  # no module names from data
    plan = make_plan(sc, base, runs=4, seed=0, study="flaky")
    res = run_campaign(plan, tmp_path / "c", progress=False)
    assert [f["run"] for f in res.failed] == [1, 3]
    sts = store.run_statuses(tmp_path / "c")
    assert [s["status"] for s in sts] == ["ok", "error", "ok", "error"]
    assert "deliberate failure of run 1" in sts[1]["error"]
    assert store.load_tables(tmp_path / "c")["values"].column("run").to_pylist() == [0, 2]
    res2 = run_campaign(plan, tmp_path / "c", resume=True, progress=False)  # failed runs are retried
    assert (res2.skipped, res2.executed, len(res2.failed)) == (2, 2, 2)
    plan_bad = make_plan(sc, base, runs=2, seed=0, study="always_fails")
    with pytest.raises(UserError, match="all 2 runs failed; run 0: UserError: target not in view"):
        run_campaign(plan_bad, tmp_path / "bad", executor=InProcessExecutor(), progress=False)
    plugins.studies.unregister("flaky")
    plugins.studies.unregister("always_fails")


MALFORMED = [
    (["--runs", "0"], "expected an integer >= 1"),
    (["--runs", "2", "--set", "campaign.study=nope"], "unknown study 'nope'"),
    (["--runs", "2", "--set", "perturbations.bogus=1"], "unknown key 'perturbations.bogus'"),
    (["--runs", "2", "--set", "perturbations.position_cov_m2=[[1,2,0],[2,1,0],[0,0,1]]"], "positive semi-definite"),
    (["--runs", "2", "--set", "perturbations.focal_length_sigma_frac=-0.1"], "focal_length_sigma_frac"),
    (["--runs", "2", "--workers", "1", "--scheduler", "tcp://127.0.0.1:9"], "not allowed with argument"),
    (["--runs", "2", "--set", "campaign.study=json:nothing_here"], "unknown study 'json:nothing_here'"),
]


@pytest.mark.parametrize("args,message", MALFORMED)
def test_malformed_plans_one_line_exit_2(tmp_path, capsys, args, message):
    rc = main(["campaign", str(SCENE), "--out", str(tmp_path / "c"), "--workers", "0", "--quiet", *args]
              if "--workers" not in args else ["campaign", str(SCENE), "--out", str(tmp_path / "c"), *args])
    err = capsys.readouterr().err
    assert rc == 2 and message in err and err.count("\n") == 1 and err.startswith("renderlab: error:")
    assert not (tmp_path / "c").exists()  # nothing written


def test_out_dir_rules(campaign, capsys):
    plan, d, _ = campaign
    base = ["campaign", str(SCENE), "--out", str(d / "c"), "--workers", "0", "--quiet", "--seed", "5"]
    tiny = [a for kv in TINY for a in ("--set", kv)]
    assert main([*base, "--runs", "3", *tiny]) == 2
    assert "pass --resume" in capsys.readouterr().err
    assert main([*base, "--runs", "3", "--resume", *tiny, "--set", "sun.irradiance_w_m2=1000"]) == 2
    assert "(scenario.sun.irradiance_w_m2 differs)" in capsys.readouterr().err
    assert main([*base, "--runs", "3", "--resume", *tiny]) == 0  # nothing left to do
    assert "0 executed now, 3 already done" in capsys.readouterr().out
    m = json.loads((d / "c" / "campaign.json").read_text())
    assert m["plan"]["seed"]["entropy"] == 5 and not Path(m["scenario_dir"]).is_absolute()


def test_unreachable_scheduler_one_line(tmp_path, capsys):
    rc = main(["campaign", str(SCENE), "--runs", "1", "--out", str(tmp_path / "c"), "--quiet",
               "--scheduler", "tcp://127.0.0.1:9", "--connect-timeout", "2"])
    err = capsys.readouterr().err
    assert rc == 2 and "cannot reach Dask scheduler at tcp://127.0.0.1:9" in err and err.count("\n") == 1


def test_truth_cache_key_follows_the_truth_code(tmp_path):
    """The cache key changes when a truth-side source changes (a stale render is never reused) and not when
    estimator/campaign code changes."""
    import shutil

    from renderlab.campaign import cache

    pkg = Path(cache.__file__).resolve().parents[1]
    copy = tmp_path / "renderlab"
    shutil.copytree(pkg, copy, ignore=shutil.ignore_patterns("__pycache__"))
    base = cache.fingerprint_truth_sources(copy)
    assert base == cache.fingerprint_truth_sources(pkg)  # the copy is byte-identical to the installation
    runner = copy / "campaign" / "runner.py"
    runner.write_text(runner.read_text() + "\n# not truth code\n")
    assert cache.fingerprint_truth_sources(copy) == base
    tiles = copy / "worlds" / "earth" / "tiles.py"
    tiles.write_text(tiles.read_text() + "\n# truth code changed\n")
    assert cache.fingerprint_truth_sources(copy) != base
