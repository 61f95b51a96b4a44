"""The published closed-loop descent campaign (results/descent_navigation): raw tables with ≥ 100 runs per method,
the study's name in its manifest, and a README whose consistency and touchdown numbers are the report's (which
tests/test_published_results.py regenerates from the tables alone)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pyarrow.parquet as pq

from renderlab.campaign.publish import is_published

FOLDER = Path(__file__).resolve().parents[1] / "results" / "descent_navigation"


def test_published_with_raw_tables_and_at_least_100_runs_per_method():
    assert is_published(FOLDER)
    assert json.loads((FOLDER / "campaign.json").read_text())["plan"]["study"] == "descent_navigation"
    t = pq.read_table(FOLDER / "tables" / "descent_filter.parquet", columns=["run", "method", "frame"]).to_pydict()
    runs = {}
    for r, m in zip(t["run"], t["method"]):
        runs.setdefault(m, set()).add(r)
    assert {"retina", "spc", "ncc_baseline"} <= set(runs)
    assert all(len(v) >= 100 for v in runs.values()), {m: len(v) for m, v in runs.items()}
    assert (FOLDER / "tables" / "descent_landmarks.parquet").is_file()


def test_readme_quotes_the_report():
    readme = (FOLDER / "README.md").read_text()
    for row in csv.DictReader(open(FOLDER / "report" / "descent_summary.csv")):
        for key in ("anees_over_6", "anis_per_dof", "touchdown_pos_err_median_m"):
            assert f"{float(row[key]):.3g}" in readme, (row["method"], key, row[key])
