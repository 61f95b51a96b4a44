"""Study ``retina_vs_spc`` with truth trajectory/pointing perturbations: every run renders its own truth.

A tiny EV5 descent (64², 2 frames, 2 spp, real Mitsuba renders) in 2 runs with a true position offset
(0.5 m per axis) and a pointing error (0.3° per camera axis). Oracles, computed here independently of the
lab's perturbed-truth code: the nominal poses of the world plan with the run's stored draw applied by
scipy (p + δp, R·Exp(δθ)), the landmark centres projected with OpenCV ``projectPoints`` in float64; the
a-priori prediction projected the same way from the perturbed truth plus the row's a-priori draw.
Cache: a re-run of a run hits its truth (no render, no new folder, same rows); the world is loaded once
for all runs; a fresh render of the same poses is byte-identical; nominal poses give the nominal images.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from tiny_ev5 import TINY_EV5_WORLD

from renderlab.cli import main

TINY = f"""name = "ev5_tiny_perturbed"
{TINY_EV5_WORLD}[trajectory]
kind = "ev5_descent"
altitudes_m = [65.0, 45.0]
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
[perturbations]
position_sigma_m = [0.5, 0.5, 0.5]
attitude_sigma_deg = 0.3
apriori_position_sigma_m = [0.2, 0.2, 0.2]
apriori_attitude_sigma_deg = 0.05
[campaign]
seed = 11
[retina_vs_spc]
methods = ["retina", "spc"]
"""
RUNS = 2


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    d = tmp_path_factory.mktemp("rvs_pert")
    (d / "tiny.toml").write_text(TINY)
    assert main(["campaign", str(d / "tiny.toml"), "--runs", str(RUNS), "--out", str(d / "camp"), "--workers", "0",
                 "--quiet"]) == 0
    runs = sorted((d / "camp" / "runs").iterdir())
    meas = [pq.read_table(r / "measurements.parquet").to_pydict() for r in runs]
    pert = [pq.read_table(r / "perturbations.parquet").to_pydict() for r in runs]
    return d, meas, pert


def _sets(d: Path) -> dict:
    """{cache key: TruthSet} of the campaign's truth cache."""
    from renderlab.files.truthset import TruthSet

    root = d / "camp" / "work" / "truth_cache"
    return {p.name: TruthSet.open(p) for p in sorted(root.iterdir()) if (p / "manifest.json").is_file()}


def _own_set(d: Path, p: dict):
    """The truth set whose manifest records this run's drawn position offset."""
    dpos = [p[f"dpos_{a}"][0] for a in "xyz"]
    own = [ts for ts in _sets(d).values()
           if ts.manifest.get("frame_specs_note", {}).get("truth_perturbation", {}).get("dposition_m") == dpos]
    assert len(own) == 1
    return own[0]


def _nominal(d: Path):
    from renderlab.scenario import load_scenario, scenario_from_dict, truth_dict
    from renderlab.worlds.base import make_plan

    sc, base = load_scenario(d / "tiny.toml")
    truth = scenario_from_dict(truth_dict(sc.to_dict()), "nominal")
    return truth, base, make_plan(truth, base).frames


def _project(centres, R_render_from_cam, pos, K, dist=None):
    import cv2

    p_cam = R_render_from_cam.inv().apply(np.asarray(centres, float) - pos)
    uv, _ = cv2.projectPoints(p_cam.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, np.zeros(5) if dist is None else dist)
    return uv.reshape(-1, 2), p_cam[:, 2] > 0


def test_each_run_truth_is_its_own_perturbed_pose_opencv(campaign):
    from scipy.spatial.transform import Rotation

    from renderlab.worlds.ev5.catalog import read_catalog

    d, meas, pert = campaign
    _, _, nominal = _nominal(d)
    assert len(_sets(d)) == RUNS  # one render per run, none of the nominal descent
    checked = 0
    for m, p in zip(meas, pert):
        ts = _own_set(d, p)
        centres = {int(mp.landmark_id): mp.center_m for mp in read_catalog(ts.path)}
        ids = sorted(centres)
        truth = ts.read_table("landmark_truth").to_pydict()
        tmap = {(f, i): (s, l) for f, i, s, l in zip(truth["frame"], truth["landmark_id"], truth["s"], truth["l"])}
        dpos = np.array([p[f"dpos_{a}"][0] for a in "xyz"])
        att = np.array([p[f"att_rotvec_{a}"][0] for a in "xyz"])
        assert np.all(np.abs(dpos) > 1e-3) and np.all(np.abs(att) > 1e-5)
        for k, spec in enumerate(nominal):
            pos = np.asarray(spec.pose.position_m, float) + dpos
            R = spec.pose.rotation * Rotation.from_rotvec(att)
            rec = ts.frames[k]
            assert rec["pose"]["position_m"] == pytest.approx(pos.tolist(), abs=1e-9)
            cam = rec["camera"]
            K = np.array([[cam["fx"], 0, cam["cx"]], [0, cam["fy"], cam["cy"]], [0, 0, 1.0]])
            uv, front = _project([centres[i] for i in ids], R, pos, K)
            inside = front & np.all((uv > -0.5) & (uv < [cam["width"] - 0.5, cam["height"] - 0.5]), axis=1)
            assert inside.sum() >= 3
            for j, lid in enumerate(ids):
                s, l = tmap[(spec.index, lid)]
                if inside[j]:
                    assert (s, l) == pytest.approx(tuple(uv[j]), abs=1e-6)
                    checked += 1
        # the rows' truth is this run's truth set, and the a-priori is drawn around the perturbed truth
        for r in range(0, len(m["frame"]), 5):
            f, lid = m["frame"][r], m["item"][r]
            assert (m["truth_s"][r], m["truth_l"][r]) == pytest.approx(tmap[(f, lid)], abs=1e-9)
            spec = nominal[[s.index for s in nominal].index(f)]
            R_ap = spec.pose.rotation * Rotation.from_rotvec(att) * Rotation.from_rotvec(
                [m[f"apriori_drot_{a}_rad"][r] for a in "xyz"])
            p_ap = np.asarray(spec.pose.position_m) + dpos + [m[f"apriori_dpos_{a}_m"][r] for a in "xyz"]
            cam = ts.frames[0]["camera"]
            K = np.array([[cam["fx"], 0, cam["cx"]], [0, cam["fy"], cam["cy"]], [0, 0, 1.0]])
            uv, _ = _project([centres[lid]], R_ap, p_ap, K)
            assert (m["pred_s"][r], m["pred_l"][r]) == pytest.approx(tuple(uv[0]), abs=1e-6)
    assert checked >= 10


def test_runs_with_different_perturbations_get_different_truth(campaign):
    d, _, pert = campaign
    a, b = _own_set(d, pert[0]), _own_set(d, pert[1])
    assert a.path != b.path
    dn_a, dn_b = a.load(0).dn.astype(float), b.load(0).dn.astype(float)
    assert np.mean(np.abs(dn_a - dn_b)) > 1.0
    ta, tb = a.read_table("landmark_truth").to_pydict(), b.read_table("landmark_truth").to_pydict()
    both = np.isfinite(ta["s"]) & np.isfinite(tb["s"])
    assert both.sum() >= 3 and np.max(np.abs(np.asarray(ta["s"])[both] - np.asarray(tb["s"])[both])) > 0.5


def test_rerun_hits_the_cache_same_rows_and_world_loaded_once(campaign):
    from renderlab.campaign import cache
    from renderlab.campaign.plan import run_seed_sequence
    from renderlab.scenario import load_scenario
    from renderlab.studies.retina_vs_spc.run import run

    d, meas, _ = campaign
    worlds = list(cache._WORLDS.values())
    assert len(worlds) == 1 and worlds[0].loads == 1  # both runs rendered from one loaded scene
    root = d / "camp" / "work" / "truth_cache"
    before = {p.name: p.stat().st_mtime_ns for p in root.iterdir()}
    sc, base = load_scenario(d / "tiny.toml")
    again = run(sc, base, 1, run_seed_sequence(11, 1), d / "camp" / "work")["measurements"].to_pydict()
    assert {p.name: p.stat().st_mtime_ns for p in root.iterdir()} == before  # hit: nothing rendered or written
    assert worlds[0].loads == 1
    for c in meas[1]:
        if c not in ("t_ms", "campaign", "run"):
            a, b = np.asarray(again[c]), np.asarray(meas[1][c])
            assert np.array_equal(a, b, equal_nan=a.dtype.kind == "f"), c


def test_same_poses_give_byte_identical_files_and_nominal_poses_the_nominal_images(campaign, tmp_path):
    from renderlab.campaign.cache import cached_frames_truthset, cached_truthset
    from renderlab.campaign.perturb import draw_perturbation
    from renderlab.campaign.plan import run_seed_sequence
    from renderlab.campaign.run_truth import perturbed_specs, run_truthset
    from renderlab.files.truthset import TruthSet
    from renderlab.scenario import load_scenario

    d, _, pert = campaign
    sc, base = load_scenario(d / "tiny.toml")
    truth, _, nominal = _nominal(d)
    draw = draw_perturbation(sc.perturbations, run_seed_sequence(11, 0).spawn(4)[0])
    assert draw.dposition_m.tolist() == [pert[0][f"dpos_{a}"][0] for a in "xyz"]
    fresh, hit = run_truthset(truth, base, tmp_path / "c1", sc.perturbations, draw)
    cached = _own_set(d, pert[0]).path
    assert not hit and fresh.name == cached.name
    files = sorted(p.relative_to(cached) for p in cached.rglob("*") if p.is_file())
    assert files == sorted(p.relative_to(fresh) for p in fresh.rglob("*") if p.is_file())
    for f in files:
        assert (cached / f).read_bytes() == (fresh / f).read_bytes(), f
    nom = TruthSet.open(cached_truthset(truth, base, tmp_path / "nom")[0])
    assert json.loads((fresh / "manifest.json").read_text())["frames"][0]["pose"] != nom.frames[0]["pose"]
    same = TruthSet.open(cached_frames_truthset(truth, base, tmp_path / "c2", perturbed_specs(nominal, type(draw)()))[0])
    for k in range(len(nom)):
        assert np.array_equal(nom.load(k).dn, same.load(k).dn)
        assert np.array_equal(nom.load(k).radiance, same.load(k).radiance)
    a, b = nom.read_table("landmark_truth").to_pydict(), same.read_table("landmark_truth").to_pydict()
    assert a.keys() == b.keys()
    for c in a:
        x, y = np.asarray(a[c]), np.asarray(b[c])
        assert np.array_equal(x, y, equal_nan=x.dtype.kind == "f"), c
