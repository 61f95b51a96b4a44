"""The published closed-loop GN&C descent (results/descent_gnc): raw tables with ≥ 100 runs × 3 landmark methods in
both modes (closed loop and replay), each closed loop flying its own trajectory, the folder small (≤ 3 MB, no file
over 1 MB), and a README that quotes the report's numbers (tests/test_published_results.py regenerates the report's
CSVs from the tables alone)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from renderlab.campaign.publish import is_published

pytestmark = pytest.mark.published
FOLDER = Path(__file__).resolve().parents[1] / "results" / "descent_gnc"
METHODS = {"retina", "spc", "ncc_baseline"}


def test_published_with_100_paired_runs_per_method_and_mode():
    assert is_published(FOLDER)
    assert json.loads((FOLDER / "campaign.json").read_text())["plan"]["study"] == "descent_gnc"
    t = pq.read_table(FOLDER / "tables" / "gnc_runs.parquet",
                      columns=["run", "method", "mode", "t_end_s", "td_e_m", "init_vel_err_max_sigma"]).to_pydict()
    runs: dict = {}
    for r, m, mo in zip(t["run"], t["method"], t["mode"]):
        runs.setdefault((m, mo), set()).add(r)
    assert set(runs) == {(m, mo) for m in METHODS for mo in ("closed", "replay")}
    assert all(len(v) >= 100 for v in runs.values()), {k: len(v) for k, v in runs.items()}
    by_run: dict = {}
    for i, r in enumerate(t["run"]):
        by_run.setdefault(r, []).append(i)
    own = 0
    for rows in by_run.values():
        assert len({t["init_vel_err_max_sigma"][i] for i in rows}) == 1          # paired draws
        closed = {(t["t_end_s"][i], t["td_e_m"][i]) for i in rows if t["mode"][i] == "closed"}
        replay = {(t["t_end_s"][i], t["td_e_m"][i]) for i in rows if t["mode"][i] == "replay"}
        assert len(replay) == 1
        own += len(closed) == len(METHODS)
    assert own == len(by_run)                  # every run: each method's closed loop flew its own path


def test_folder_is_small():
    sizes = {p.relative_to(FOLDER).as_posix(): p.stat().st_size for p in FOLDER.rglob("*") if p.is_file()}
    assert sum(sizes.values()) <= 3 * 2**20, sum(sizes.values())
    assert max(sizes.values()) <= 2**20, max(sizes.items(), key=lambda kv: kv[1])
    assert not [n for n in sizes if n.endswith(".svg")]


def test_readme_quotes_the_report():
    readme = " ".join((FOLDER / "README.md").read_text(encoding="utf-8").split())
    rows = list(csv.DictReader(open(FOLDER / "report" / "gnc_summary.csv")))
    assert {(r["method"], r["mode"]) for r in rows} == {(m, mo) for m in METHODS for mo in ("closed", "replay")}
    for r in rows:
        if r["mode"] != "closed":
            continue
        for key in ("td_h_median_m", "td_h_p95_m", "anees_over_6", "delta_v_mean_mps"):
            assert f"{float(r[key]):.3g}" in readme, (r["method"], key, r[key])
        assert f"{r['track_lost_runs']} of {r['n_runs']}" in readme or int(r["track_lost_runs"]) == 0
    assert "renderlab campaign" in readme and "renderlab publish" in readme
