"""The error budget (renderlab/studies/retina_vs_spc/budget*.py): configurations from scenario keys,
its statistics against direct numpy computations on synthetic tables with known bias/noise, the quadrature check
on additive vs interacting sources, and the parts of the published report (its regeneration: test_result_folders)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow as pa
import pytest

from renderlab.campaign.oat_budget import get_key
from renderlab.errors import UserError
from renderlab.scenario import load_scenario
from renderlab.stats import oat_budget as S
from renderlab.studies.retina_vs_spc.budget import plan as B
from renderlab.studies.retina_vs_spc.budget.report import write_report
from renderlab.studies.retina_vs_spc.budget.runner import main

REPO = Path(__file__).resolve().parents[1]
PUBLISHED = REPO / "results" / "error_budget"


def _base():
    sc, _ = load_scenario(REPO / "results" / "retina_vs_spc" / "scenario.toml")
    return sc.to_dict()


def test_configurations_switch_one_source_each_by_scenario_keys():
    base = B.with_section(_base())
    cfgs = {c["config"]: c for c in B.budget_configs(base)}
    assert list(cfgs) == ["all_off", *B.SOURCES, "all_on", "no_shadows"]
    ns = cfgs["no_shadows"]["scenario"]   # all off + no cast shadows in the truth (the methods: budget_shadows)
    assert ns["render"]["shadows"] is False and not B.stochastic(ns) and cfgs["no_shadows"]["source"] == ""
    assert all(get_key(ns, k) == B.OFF[k] for k in B.OFF) and base["render"].get("shadows", True) is True
    off = cfgs["all_off"]["scenario"]
    assert off["world"]["law"] == "mcewen" and off["world"]["mapping_error_m"] == 0
    assert off["retina_vs_spc"]["sensor_noise"] is False and not B.stochastic(off)
    assert off["perturbations"]["apriori_position_sigma_m"] == [0.0, 0.0, 0.0]
    assert cfgs["all_on"]["scenario"]["world"] == base["world"]
    for src, (_, keys) in B.SOURCES.items():
        sc = cfgs[src]["scenario"]
        for k in B.OFF:  # exactly this source's keys differ from all off
            assert (get_key(sc, k) == get_key(base, k)) if k in keys else (get_key(sc, k) == B.OFF[k]), (src, k)
        assert sc["retina_vs_spc"]["methods"] == list(B.METHODS)
    assert B.stochastic(cfgs["sensor_noise"]["scenario"]) and B.stochastic(cfgs["sun_knowledge"]["scenario"])
    assert not B.stochastic(cfgs["mapping_error"]["scenario"]) and not B.stochastic(cfgs["photometric_law"]["scenario"])


def test_a_scenario_without_the_keys_is_refused():
    base = _base()
    del base["world"]["mapping_error_m"]
    with pytest.raises(UserError, match="world.mapping_error_m"):
        B.budget_configs(base)


def _synthetic(rng, interact: bool, n_lm=60, runs=12):
    """all_off: per-landmark bias 0.05; source a: + per-landmark bias 0.10; source b: + noise 0.08 per run;
    all_on = both added (independent) or, with ``interact``, source a's bias doubled when b is on."""
    b0, ba = rng.normal(0, 0.05, n_lm), rng.normal(0, 0.10, n_lm)
    rows = []
    for cfg, nr in (("all_off", 1), ("a", 1), ("b", runs), ("all_on", runs)):
        for r in range(nr):
            noise = rng.normal(0, 0.08, (n_lm, 2)) if cfg in ("b", "all_on") else np.zeros((n_lm, 2))
            gain = 2.0 if (interact and cfg == "all_on") else 1.0
            e = b0[:, None] + (gain * ba[:, None] if cfg in ("a", "all_on") else 0) + noise
            for k in range(n_lm):
                rows.append({"config": cfg, "run": r, "frame": k % 3, "item": k, "err_s": e[k, 0], "err_l": e[k, 1]})
    n = len(rows)
    cols = {c: [row.get(c) for row in rows] for c in ("config", "run", "frame", "item", "err_s", "err_l")}
    table = {**cols, "method": ["retina"] * n, "peak": ["retina_3x3"] * n, "truth_s": [10.0] * n,
             "truth_l": [10.0] * n, "has_result": [True] * n, "reason": ["ok"] * n, "outlier": [False] * n,
             "truth_visible": [True] * n, "score": [0.9] * n, "search_px": [4] * n, "n_pixels": [100] * n,
             "gsd_ratio": [1.0] * n, "phase_deg": [30.0] * n, "shadow_fraction": [0.0] * n,
             "pred_shadow_fraction": [0.0] * n, "crlb_s": [0.01] * n, "crlb_l": [0.01] * n, "range_m": [100.0] * n}
    configs = [{"config": c, "source": s, "description": c, "runs": nr, "overrides": {}}
               for c, s, nr in (("all_off", "", 1), ("a", "a", 1), ("b", "b", runs), ("all_on", "", runs))]
    return pa.table({c: table[c] for c in B.BUDGET_TABLES.columns}), configs


def test_statistics_match_direct_numpy_computations():
    rng = np.random.default_rng(5)
    t, _ = _synthetic(rng, interact=False)
    cols = S.columns(t)
    s = S.sample(cols, "b", "retina", np.ones(t.num_rows, bool), "s", 12)
    e = np.asarray(t.column("err_s").to_pylist())[np.asarray(t.column("config").to_pylist()) == "b"]
    lm = np.asarray(t.column("item").to_pylist())[np.asarray(t.column("config").to_pylist()) == "b"]
    ones = np.ones(cols["n_clusters"])
    means = np.array([e[lm == k].mean() for k in range(60)])
    sds = np.array([e[lm == k].var(ddof=1) for k in range(60)])
    assert S.weighted_stat("bias_rms", s, ones, 1.0) == pytest.approx(np.sqrt(np.mean(means ** 2)), rel=1e-12)
    assert S.weighted_stat("noise_sd", s, ones, 1.0) == pytest.approx(np.sqrt(sds.mean()), rel=1e-12)
    assert S.weighted_stat("std", s, ones, 1.0) == pytest.approx(np.std(e, ddof=1), rel=1e-12)
    mad = np.median(np.abs(e - np.median(e)))
    assert S.weighted_stat("robust_sigma", s, ones, 1.0) == pytest.approx(1.482602218505602 * mad, rel=1e-9)
    assert 0.06 < S.weighted_stat("noise_sd", s, ones, 1.0) < 0.10  # the drawn 0.08
    both = S.sample(cols, "b", "retina", np.ones(t.num_rows, bool), "both", 12)  # axes pooled, spread per axis
    el = np.asarray(t.column("err_l").to_pylist())[np.asarray(t.column("config").to_pylist()) == "b"]
    var_both = [x[lm == k].var(ddof=1) for x in (e, el) for k in range(60)]
    assert S.weighted_stat("noise_sd", both, ones, 1.0) == pytest.approx(np.sqrt(np.mean(var_both)), rel=1e-12)
    w = S.joint_weights(cols["n_clusters"], 3, 1)  # a replicate = the rows of the drawn landmarks repeated
    clu = cols["cluster"][np.asarray(t.column("config").to_pylist()) == "b"]
    rep = np.concatenate([e[clu == j] for j in np.repeat(np.arange(60), w[0].astype(int))])
    assert S.weighted_stat("std", s, w[0], 1.0) == pytest.approx(np.std(rep, ddof=1), rel=1e-12)


@pytest.mark.parametrize("interact, verdict", [(False, "PASS"), (True, "FAIL")])
def test_quadrature_check_passes_additive_sources_and_flags_an_interaction(interact, verdict, tmp_path):
    t, configs = _synthetic(np.random.default_rng(11), interact)
    B.BUDGET_TABLES.write(tmp_path / "b", configs, t, pa.table({"config": ["all_off"], "run": [0]}), {"command": "test"})
    assert main(["report", str(tmp_path / "b")]) == 0   # the budget's command line, from the tables alone
    terms = (tmp_path / "b" / "report" / "budget_terms.csv").read_text().splitlines()
    head = terms[0].split(",")
    rows = [dict(zip(head, line.split(","))) for line in terms[1:]]
    chk = next(r for r in rows if r["statistic"] == "std" and r["term"] == "sum_over_all_on" and r["axis"] == "both"
               and r["subset"] == "all")
    assert chk["check"] == verdict, chk
    noise = next(r for r in rows if r["statistic"] == "noise_sd" and r["term"] == "b" and r["axis"] == "both"
                 and r["subset"] == "all")
    assert float(noise["lo"]) < 0.08 < float(noise["hi"])  # the drawn noise inside its interval
    assert {p.name for p in (tmp_path / "b" / "report").iterdir()} >= {"error_budget.png", "budget_table.md",
                                                                        "budget_summary.csv"}
    assert not list((tmp_path / "b" / "report").glob("*.svg")), "SVG only with renderlab report --svg"


def test_report_refuses_a_folder_without_tables(tmp_path):
    with pytest.raises(UserError, match="not an error-budget folder"):
        write_report(tmp_path)
    assert not (tmp_path / "report").exists()


@pytest.mark.published
@pytest.mark.skipif(not PUBLISHED.is_dir(), reason="results/error_budget not published yet")
def test_published_budget_report_has_every_part():
    """The committed report (its regeneration from the tables: tests/test_result_folders.py, published tier): PNG
    figures only, the navigation and shadow sections, the command that made the tables."""
    committed = {p.name for p in (PUBLISHED / "report").iterdir()}
    assert {"error_budget.png", "budget_navigation.png", "budget_navigation.csv",
            "budget_navigation_validation.csv", "budget_table.md"} <= committed
    assert not list((PUBLISHED / "report").glob("*.svg")), "PNG only; SVG with renderlab report --svg"
    md = (PUBLISHED / "report" / "budget_table.md").read_text()
    assert "| shadow_approximation |" in md and "### navigation: geometric all-on vs the rendered" in md
    manifest = json.loads((PUBLISHED / "budget.json").read_text())
    assert manifest["command"].startswith("python -m renderlab.studies.retina_vs_spc.budget run")


def test_sensor_noise_switch_gives_the_mean_of_the_noisy_exposures():
    """[retina_vs_spc] sensor_noise = false: the DN is the noise-free exposure, i.e. the mean of many noisy
    re-exposures of the same radiance (to their standard error), rounded; true: a new draw per seed."""
    from dataclasses import dataclass
    from types import SimpleNamespace

    from renderlab.campaign.perturb import draw_perturbation
    from renderlab.scenario.campaign import PerturbationConfig
    from renderlab.sensor.model import SensorOptions
    from renderlab.studies.retina_vs_spc.run import BelievedTruthSet

    @dataclass
    class Frame:
        radiance: np.ndarray
        dn: np.ndarray

    rad = np.random.default_rng(3).uniform(2.0, 30.0, (8, 8)).astype(np.float32)
    rec = {"index": 0, "camera": {"model": "pinhole", "width": 8, "height": 8, "fx": 50.0, "fy": 50.0, "cx": 3.5,
                                  "cy": 3.5}, "sun": {"direction_render": [0.0, 0.0, 1.0]}, "sensor": {"exposure_s": 0.5 * SensorOptions().exposure_s}}
    ts = SimpleNamespace(path=Path("fake"), frames=[rec], load=lambda i: Frame(rad, np.zeros((8, 8), np.uint16)))
    draw = draw_perturbation(PerturbationConfig(), np.random.SeedSequence(0))
    opts = SensorOptions()
    quiet = BelievedTruthSet(ts, draw, opts, [0], noise=False).load(0).dn
    noisy = np.array([BelievedTruthSet(ts, draw, opts, [s]).load(0).dn for s in range(300)], float)
    assert quiet.dtype == np.uint16 and np.all(noisy.std(0) > 1)  # the noise is well above quantisation
    assert np.all(np.abs(quiet - noisy.mean(0)) <= 4 * noisy.std(0) / np.sqrt(300) + 0.5)
    assert not np.array_equal(noisy[0], noisy[1])
