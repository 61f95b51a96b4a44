"""Geometric measurement sources of the descent study (renderlab/studies/descent_navigation/sources.py, eq. G1).

Oracles independent of the study's code: OpenCV's ``projectPoints`` of the maplet centres at the true poses; the
published rendered campaign's ``truth_s``/``truth_l`` columns (made from a rendered truth set's manifest) for the
frames the geometric path takes from the world's plan; χ² bands of the filter's NEES/NIS (scipy). The consistency
test can fail both ways: a model-matched source outside its band (the filter or the source is wrong) or a
0.2 px bias inside it (the source does not inject, or the test has no power).
"""

from __future__ import annotations

import copy
import tomllib
from pathlib import Path

import cv2
import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pytest
from scipy.stats import chi2

from renderlab.campaign.plan import run_seed_sequence
from renderlab.cli import main
from renderlab.scenario import scenario_from_dict

RESULTS = Path(__file__).resolve().parents[1] / "results"
GEOMETRIC = RESULTS / "descent_navigation_geometric" / "scenario.toml"


def _scenario(sources: list[dict], **dn):
    d = tomllib.loads(GEOMETRIC.read_text())
    d = copy.deepcopy(d)
    d["descent_navigation"]["sources"] = sources
    d["descent_navigation"].update(dn)
    return scenario_from_dict(d, "test scenario")


def _runs(scenario, n: int, tmp_path) -> pa.Table:
    from renderlab.studies.descent_navigation.run import run

    out = [run(scenario, GEOMETRIC.parent, i, run_seed_sequence(int(scenario.campaign.seed), i), tmp_path)
           for i in range(n)]
    return {k: pa.concat_tables([o[k] for o in out]).to_pydict() for k in out[0]}


def _project(p_body, pos, R_body_from_cam, cam):
    R = R_body_from_cam.T
    rvec, _ = cv2.Rodrigues(R)
    K = np.array([[cam.fx, 0, cam.cx], [0, cam.fy, cam.cy], [0, 0, 1.0]])
    out, _ = cv2.projectPoints(np.asarray(p_body, float).reshape(-1, 1, 3), rvec, -R @ pos, K, None)
    return out.reshape(-1, 2)


def test_planned_frames_are_the_rendered_truth_sets():
    """The geometric path renders nothing: its true poses (the world's plan) give the published rendered campaign's
    truth pixels (a truth set's manifest poses; its full landmark table, recovered by the git command its
    raw_tables.json records) to 1e-6 px."""
    from renderlab.campaign.compact import recover_raw_table
    from renderlab.scenario import load_scenario
    from renderlab.studies.descent_navigation.run import section
    from renderlab.studies.descent_navigation.truth import planned_descent

    folder = RESULTS / "descent_navigation"
    sc, base = load_scenario(folder / "scenario.toml")
    frames, _, maplets = planned_descent(sc, base, section(sc))
    centre = {int(m.landmark_id): np.asarray(m.center_m, float) for m in maplets}
    raw = recover_raw_table(folder / "tables", "descent_landmarks")
    if raw is None:
        pytest.skip("the full landmark table is not recoverable in this checkout (no git history)")
    t = raw.filter((pc.field("run") == 0) & (pc.field("method") == "retina")).to_pydict()
    assert len(t["frame"]) > 50
    for k, item, s, l in zip(t["frame"], t["item"], t["truth_s"], t["truth_l"]):
        px = _project(centre[item], frames["pos_true"][k], frames["R_true"][k], frames["cameras"][k])[0]
        assert abs(px[0] - s) < 1e-6 and abs(px[1] - l) < 1e-6, (k, item, px, s, l)


def test_the_source_injects_eq_g1(tmp_path):
    """Noise off: the measurement minus OpenCV's true pixel is μ, κ (p − c), or one constant per landmark (σ_b)."""
    from renderlab.studies.descent_navigation.run import section
    from renderlab.studies.descent_navigation.truth import planned_descent

    srcs = [{"name": "mu", "bias_px": [0.1, -0.05], "sigma_noise_px": 0.0},
            {"name": "kappa", "scale": 1e-3, "sigma_noise_px": 0.0},
            {"name": "beta", "sigma_bias_px": 0.2, "sigma_noise_px": 0.0}]
    sc = _scenario(srcs)
    frames, _, maplets = planned_descent(sc, GEOMETRIC.parent, section(sc))
    centre = {int(m.landmark_id): np.asarray(m.center_m, float) for m in maplets}
    lm = _runs(sc, 1, tmp_path)["descent_landmarks"]
    cam = frames["cameras"][0]
    per = {}
    for name, k, item, ms, ml in zip(lm["method"], lm["frame"], lm["item"], lm["meas_s"], lm["meas_l"]):
        p = _project(centre[item], frames["pos_true"][k], frames["R_true"][k], cam)[0]
        e = np.array([ms, ml]) - p
        if name == "mu":
            assert np.allclose(e, [0.1, -0.05], atol=1e-6)
        elif name == "kappa":
            assert np.allclose(e, 1e-3 * (p - [cam.cx, cam.cy]), atol=1e-6)
        else:
            per.setdefault(item, []).append(e)
    assert len(per) >= 8
    assert all(np.allclose(v, v[0], atol=1e-6) for v in per.values())        # constant over the track
    spread = np.array([v[0] for v in per.values()])
    assert 0.1 < spread.std() < 0.3                                         # rms 0.2 px over the landmarks


N_RUNS = 40


def _image_anees(t, name) -> np.ndarray:
    """ANEES (6 dof) per image over the runs of source ``name``."""
    m, f, nees = np.array(t["method"]), np.array(t["frame"]), np.array(t["nees"], float)
    return np.array([nees[(m == name) & (f == k)].mean() for k in range(f.max() + 1)])


def _run_mean_ci(t, name, seed=0) -> tuple[float, float, float]:
    """Mean over runs of the run's time-mean NEES/6, and its 95 % bootstrap interval (whole runs resampled)."""
    m, f, r, nees = (np.array(t[k]) for k in ("method", "frame", "run", "nees"))
    v = np.array([nees[(m == name) & (f >= 0) & (r == i)].astype(float).mean() / 6 for i in sorted(set(r))])
    boot = v[np.random.default_rng(seed).integers(0, v.size, (2000, v.size))].mean(1)
    return float(v.mean()), float(np.percentile(boot, 2.5)), float(np.percentile(boot, 97.5))


def _anis_inside(t, name) -> bool:
    m, f, nis, dof = np.array(t["method"]), np.array(t["frame"]), np.array(t["nis"], float), np.array(t["dof"])
    s = (m == name) & (f >= 0) & np.isfinite(nis)
    lo, hi = chi2.ppf([0.025, 0.975], dof[s].sum()) / dof[s].sum()
    return bool(lo <= nis[s].sum() / dof[s].sum() <= hi)


def test_model_matched_source_is_consistent_and_a_bias_is_not(tmp_path):
    """N runs of the published scenario's model-matched source (the truth's gravity is not the filter's, on
    purpose): the run-mean ANEES/6 has 1 inside its 95 % run-bootstrap interval and ANIS/dof is inside its χ² band;
    a 0.2 px common bias (same runs, same noise draws) is far outside, in the state only (the innovations absorb
    a common bias into the position: ANIS stays in its band). With the truth's gravity set to the filter's (fully
    model-matched), the per-image ANEES is inside its χ²(6N)/N band at the last image and at ≥ 80 % of the images."""
    sc = _scenario([{"name": "matched"}, {"name": "biased", "bias_px": [0.2, 0.2]}])
    t = _runs(sc, N_RUNS, tmp_path)["descent_filter"]
    assert not any(t["track_lost"])
    mean, lo, hi = _run_mean_ci(t, "matched")
    assert lo <= 1.0 <= hi, (mean, lo, hi)
    assert _anis_inside(t, "matched")
    mean_b, lo_b, _ = _run_mean_ci(t, "biased")
    assert lo_b > 3.0, mean_b
    band = chi2.ppf([0.025, 0.975], 6 * N_RUNS) / N_RUNS
    biased = _image_anees(t, "biased")
    assert np.all(biased > band[1]), biased

    t = _runs(_scenario([{"name": "matched"}], gm_true_m3_s2=3.19, j2_true=0.0), N_RUNS, tmp_path)["descent_filter"]
    a = _image_anees(t, "matched")
    inside = (band[0] <= a) & (a <= band[1])
    assert inside[-1] and inside.mean() >= 0.8, a / 6
    assert _anis_inside(t, "matched")


def test_unknown_source_kind_and_filter_are_one_line_errors(tmp_path, capsys):
    text = GEOMETRIC.read_text()
    for key, (old, new), msg in (("kind", ('kind = "geometric"', 'kind = "geometrik"'), "unknown measurement source"),
                                 ("filter", ('filter = "descent_ekf"', 'filter = "descent_ekff"'), "unknown filter")):
        assert old in text
        p = tmp_path / f"{key}.toml"
        p.write_text(text.replace(old, new, 1))
        assert main(["campaign", str(p), "--runs", "1", "--out", str(tmp_path / key), "--quiet"]) != 0
        err = capsys.readouterr().err.strip()
        assert msg in err and "Traceback" not in err and len(err.splitlines()) == 1, err


def test_the_published_tables_give_the_report_of_the_raw_tables(tmp_path):
    """The study's publish_tables (per-row filter errors, NEES and NIS; the landmarks and the 1σ as sums per
    method and run / tier / image) gives the same report CSVs as the full tables of a tiny campaign in which the gate
    rejects landmarks (gate probability 0.95: rows that are not kept exist and are dropped), is idempotent, and its
    sums give what direct numpy gives on the raw rows (kept-landmark bias, std and rms, the filter's 3σ, the
    calibration fit of every method and tier)."""
    import csv

    from renderlab.stats.consistency import tracked
    from renderlab.studies.descent_navigation import STUDY
    from renderlab.studies.descent_navigation.calibrate import fit, fit_method
    from renderlab.studies.descent_navigation.report import report_sections
    from renderlab.studies.descent_navigation.run import run

    sc = _scenario([{"name": "matched"}, {"name": "biased", "bias_px": [0.1, 0.1], "sigma_bias_px": 0.05}],
                   gate_probability=0.95)
    out = [run(sc, GEOMETRIC.parent, i, run_seed_sequence(int(sc.campaign.seed), i), tmp_path) for i in range(3)]
    raw = {k: pa.concat_tables([o[k] for o in out]) for k in out[0]}
    small = STUDY.publish_tables(raw)
    assert "descent_landmarks" not in small
    assert {"descent_images", "descent_landmark_runs", "descent_landmark_tiers", "descent_landmark_fit"} <= set(small)
    assert small["descent_filter"].num_rows == raw["descent_filter"].num_rows
    assert small["descent_filter"].num_columns < raw["descent_filter"].num_columns
    again = STUDY.publish_tables(small)
    assert set(again) == set(small) and all(again[k].equals(small[k]) for k in small)
    csvs = {}
    for name, tables in (("raw", raw), ("small", small)):
        (tmp_path / name).mkdir()
        report_sections(tables, tmp_path / name)
        csvs[name] = {p.name: p.read_text() for p in sorted((tmp_path / name).glob("*.csv"))}
    assert {"descent_summary.csv", "descent_independence.csv", "descent_pattern.csv", "descent_sources.csv",
            "descent_bias_by_tier.csv"} <= set(csvs["raw"])
    assert csvs["small"] == csvs["raw"]

    def read(name):
        return list(csv.DictReader(open(tmp_path / "small" / name)))

    f = tracked(raw["descent_filter"]).to_pydict()
    ok_runs = {(m, r) for m, r in zip(f["method"], f["run"])}
    lm = raw["descent_landmarks"].to_pydict()
    rows = [i for i in range(len(lm["run"])) if lm["kept"][i] and (lm["method"][i], lm["run"][i]) in ok_runs]
    col = {k: np.array([lm[k][i] for i in rows]) for k in ("method", "err_s", "err_l", "gsd_m", "spacing_m")}
    for r in read("descent_summary.csv"):
        e = col["err_s"][col["method"] == r["method"]]
        assert float(r["kept_bias_s_px"]) == pytest.approx(np.mean(e), rel=1e-5, abs=1e-12)
        assert float(r["kept_std_s_px"]) == pytest.approx(np.std(e, ddof=1), rel=1e-5)
    for r in read("descent_bias_by_tier.csv"):
        k = (col["method"] == r["method"]) & (col["spacing_m"] == float(r["spacing_m"]))
        assert float(r["rms_l_px"]) == pytest.approx(np.sqrt(np.mean(col["err_l"][k] ** 2)), rel=1e-5)
        assert float(r["rms_l_m"]) == pytest.approx(np.sqrt(np.mean((col["err_l"][k] * col["gsd_m"][k]) ** 2)),
                                                    rel=1e-5)
    fc = {k: np.array(v) for k, v in f.items() if k in ("method", "frame", "nees", "sig_u_m")}
    for r in read("descent_timeseries.csv"):
        k = (fc["method"] == r["method"]) & (fc["frame"] == int(r["frame"])) & np.isfinite(fc["nees"])
        assert float(r["pos3sig_u_m"]) == pytest.approx(3 * np.sqrt(np.mean(fc["sig_u_m"][k] ** 2)), rel=1e-5)
    res = fit(small["descent_landmark_fit"])
    every = {k: np.array(v) for k, v in raw["descent_landmarks"].to_pydict().items()}
    n = 0
    for m, by in res.items():
        for sp, got in by.items():
            k = (every["method"] == m) & every["kept"] & (every["spacing_m"] == sp)
            want = fit_method(every["run"][k], every["item"][k], every["err_s"][k], every["err_l"][k],
                              every["gsd_m"][k])
            assert repr(got) == repr(want)
            n += 1
    assert n >= 2
