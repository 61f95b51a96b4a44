"""The published geometric descent campaign (results/descent_navigation_geometric) and its companions: raw tables with
≥ 100 runs per source, the injected errors of the scenario in the tables, a README that quotes the report (which
tests/test_published_results.py regenerates from the parent's tables; the companions are regenerated here), and
companions that differ from the parent only in what their header says, run by run paired (same seeds)."""

from __future__ import annotations

import csv
import json
import shutil
import tomllib
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from renderlab.campaign.publish import is_published

FOLDER = Path(__file__).resolve().parents[1] / "results" / "descent_navigation_geometric"
COMPANIONS = {"gravity_matched": {"gm_true_m3_s2": 3.19, "j2_true": 0.0}, "ekf_1iter": {"iterations": 1},
              "q_acc_x10": {"q_acc_m2_s3": 1e-9}, "sigma_0.3px": {"sigma_px": 0.3},
              "map_states": {"map_states": "estimate", "map_sigma_h_m": 0.01}}
pytestmark = pytest.mark.published
ALL = [FOLDER] + [FOLDER / c for c in COMPANIONS]


@pytest.mark.parametrize("folder", ALL, ids=lambda p: p.name)
def test_published_with_raw_tables_and_at_least_100_runs_per_source(folder):
    assert is_published(folder)
    assert json.loads((folder / "campaign.json").read_text())["plan"]["study"] == "descent_navigation"
    sc = tomllib.loads((folder / "scenario.toml").read_text())["descent_navigation"]
    assert sc["methods"] == []                                    # geometric sources only: nothing rendered
    t = pq.read_table(folder / "tables" / "descent_filter.parquet",
                      columns=["run", "method", "inj_bias_s_px", "inj_sigma_bias_px", "inj_scale"]).to_pydict()
    runs, inj = {}, {}
    for r, m, mu, sb, k in zip(*t.values()):
        runs.setdefault(m, set()).add(r)
        inj.setdefault(m, set()).add((mu, sb, k))
    assert set(runs) == {s["name"] for s in sc["sources"]}
    assert all(len(v) >= 100 for v in runs.values()), {m: len(v) for m, v in runs.items()}
    for s in sc["sources"]:
        assert inj[s["name"]] == {(s.get("bias_px", [0, 0])[0], s.get("sigma_bias_px", 0), s.get("scale", 0))}


def test_the_sweep_has_the_issue_biases():
    names = {s["name"] for s in tomllib.loads((FOLDER / "scenario.toml").read_text())["descent_navigation"]["sources"]}
    assert {"matched", "bias_0.02px", "bias_0.05px", "bias_0.1px", "bias_0.2px"} <= names


@pytest.mark.parametrize("folder", ALL, ids=lambda p: p.name)
def test_readme_quotes_the_report(folder):
    readme = (FOLDER / "README.md").read_text()
    for row in csv.DictReader(open(folder / "report" / "descent_sources.csv")):
        for key in ("anees_over_6", "anis_per_dof", "touchdown_pos_err_rms_m"):
            assert f"{float(row[key]):.3g}" in readme, (folder.name, row["source"], key, row[key])


@pytest.mark.parametrize("nested", list(COMPANIONS))
def test_the_companions_regenerate_from_their_tables(nested, tmp_path, capsys):
    from renderlab.cli import main

    folder = FOLDER / nested
    copy = tmp_path / nested
    shutil.copytree(folder, copy, ignore=shutil.ignore_patterns("report"))
    assert main(["report", str(copy), "--tables-only"]) == 0
    capsys.readouterr()
    committed = sorted((folder / "report").glob("*.csv"))
    assert committed
    for p in committed:
        assert (copy / "report" / p.name).read_text() == p.read_text(), p.name


@pytest.mark.parametrize("nested", list(COMPANIONS))
def test_a_companion_differs_from_the_parent_only_as_declared(nested):
    """The same world, trajectory, seeds and filter options but the declared ones; the same initial estimates."""
    a = tomllib.loads((FOLDER / "scenario.toml").read_text())
    b = tomllib.loads((FOLDER / nested / "scenario.toml").read_text())
    for k, v in COMPANIONS[nested].items():
        assert b["descent_navigation"].pop(k) == v and a["descent_navigation"].pop(k) != v
    for d in (a, b):
        d.pop("name"), d.pop("description"), d["descent_navigation"].pop("sources")
    assert a == b
    cols = ["run", "method", "frame", "err_e_m", "err_n_m", "err_u_m"]
    prior = {}
    for f in (FOLDER, FOLDER / nested):
        t = pq.read_table(f / "tables" / "descent_filter.parquet", columns=cols).to_pydict()
        prior[f] = {r: (e, n, u) for r, m, k, e, n, u in zip(*(t[c] for c in cols)) if k == -1}
    common = set(prior[FOLDER]) & set(prior[FOLDER / nested])          # sigma_0.3px: runs 0..99 of the parent's 200
    assert len(common) >= 100 and common == set(prior[FOLDER / nested])
    assert all(prior[FOLDER][r] == prior[FOLDER / nested][r] for r in common)
