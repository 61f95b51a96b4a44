"""The published closed-loop descent campaigns (results/descent_navigation, results/descent_navigation_map_states):
raw tables with ≥ 100 runs per method, the study's name in the manifest, and a README whose consistency and
touchdown numbers are the report's (which tests/test_published_results.py regenerates from the tables alone). The
map-state campaign's declared landmark error model is the fit of its calibration campaign's tables (a nested
published folder, regenerated here), made with other seeds; its companion without map states (map_states_off/, same seeds) too."""

from __future__ import annotations

import csv
import json
import shutil
import tomllib
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from renderlab.campaign.publish import is_published

pytestmark = pytest.mark.published
RESULTS = Path(__file__).resolve().parents[1] / "results"
FOLDERS = [RESULTS / "descent_navigation", RESULTS / "descent_navigation_map_states"]
CALIBRATION = RESULTS / "descent_navigation_map_states" / "calibration"


@pytest.mark.parametrize("folder", FOLDERS, ids=lambda p: p.name)
def test_published_with_raw_tables_and_at_least_100_runs_per_method(folder):
    assert is_published(folder)
    assert json.loads((folder / "campaign.json").read_text())["plan"]["study"] == "descent_navigation"
    t = pq.read_table(folder / "tables" / "descent_filter.parquet", columns=["run", "method", "frame"]).to_pydict()
    runs = {}
    for r, m in zip(t["run"], t["method"]):
        runs.setdefault(m, set()).add(r)
    assert {"retina", "spc", "ncc_baseline"} <= set(runs)
    assert all(len(v) >= 100 for v in runs.values()), {m: len(v) for m, v in runs.items()}
    assert (folder / "tables" / "descent_landmark_runs.parquet").is_file()


@pytest.mark.parametrize("folder", FOLDERS, ids=lambda p: p.name)
def test_readme_quotes_the_report(folder):
    readme = (folder / "README.md").read_text()
    for row in csv.DictReader(open(folder / "report" / "descent_summary.csv")):
        for key in ("anees_over_6", "anis_per_dof", "touchdown_pos_err_median_m"):
            assert f"{float(row[key]):.3g}" in readme, (row["method"], key, row[key])


def test_map_state_campaign_declares_the_calibration_fit_made_on_other_seeds():
    from renderlab.studies.descent_navigation.calibrate import fit

    folder = RESULTS / "descent_navigation_map_states"
    sc = tomllib.loads((folder / "scenario.toml").read_text())
    cal = tomllib.loads((CALIBRATION / "scenario.toml").read_text())
    assert sc["campaign"]["seed"] != cal["campaign"]["seed"]
    assert json.loads((folder / "campaign.json").read_text())["plan"]["seed"]["entropy"] == sc["campaign"]["seed"]
    assert json.loads((CALIBRATION / "campaign.json").read_text())["plan"]["seed"]["entropy"] == cal["campaign"]["seed"]
    dn = sc["descent_navigation"]
    assert dn["map_realisation"] == cal["descent_navigation"]["map_realisation"] == "per_run"
    assert dn["map_states"] == "estimate" and cal["descent_navigation"]["map_states"] == "off"
    res = fit(pq.read_table(CALIBRATION / "tables" / "descent_landmark_fit.parquet"))
    declared = dn["landmark_error_by_method"]
    assert set(declared) == set(res)
    for m, rows in declared.items():
        assert [r[0] for r in rows] == list(res[m])
        for sp, s_px, s_map in rows:
            assert float(f"{res[m][sp]['sigma_px']:.3g}") == s_px and float(f"{res[m][sp]['sigma_map_h_m']:.3g}") == s_map


@pytest.mark.parametrize("nested", ["calibration", "map_states_off"])
def test_the_nested_campaigns_regenerate_from_their_tables(nested, tmp_path, capsys):
    from renderlab.cli import main

    folder = RESULTS / "descent_navigation_map_states" / nested
    assert is_published(folder)
    copy = tmp_path / nested
    shutil.copytree(folder, copy, ignore=shutil.ignore_patterns("report"))
    assert main(["report", str(copy), "--tables-only"]) == 0
    capsys.readouterr()
    committed = sorted((folder / "report").glob("*.csv"))
    assert committed
    for p in committed:
        assert (copy / "report" / p.name).read_text() == p.read_text(), p.name


def test_the_map_state_companion_differs_only_in_its_map_states():
    """map_states_off: the same scenario and seeds, map_states off; the same initial estimates run by run."""
    folder = RESULTS / "descent_navigation_map_states"
    a = tomllib.loads((folder / "scenario.toml").read_text())
    b = tomllib.loads((folder / "map_states_off" / "scenario.toml").read_text())
    assert b["descent_navigation"].pop("map_states") == "off" and a["descent_navigation"].pop("map_states") != "off"
    a.pop("name"), b.pop("name")
    assert a == b
    cols = ["run", "method", "frame", "err_e_m", "err_n_m", "err_u_m"]
    ta = pq.read_table(folder / "tables" / "descent_filter.parquet", columns=cols).to_pydict()
    tb = pq.read_table(folder / "map_states_off" / "tables" / "descent_filter.parquet", columns=cols).to_pydict()
    def prior(t):
        return {(r, m): (e, n, u) for r, m, f, e, n, u in zip(*(t[c] for c in cols)) if f == -1}

    assert prior(ta) == prior(tb)
