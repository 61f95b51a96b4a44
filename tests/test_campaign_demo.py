"""The demo campaign (``renderlab.demo_campaign``) end to end with 2 runs: real render, both methods, report."""

from __future__ import annotations

import csv

import pyarrow.parquet as pq


def test_demo_campaign_writes_report_with_both_methods_and_resumes(tmp_path):
    from renderlab.demo_campaign import run_demo_campaign

    html = run_demo_campaign(tmp_path / "demo", progress=False, runs=2)
    assert html == tmp_path / "demo" / "report" / "index.html" and html.is_file()
    rows = list(csv.DictReader((html.parent / "summary.csv").open()))
    assert {r["method"] for r in rows} >= {"retina", "spc"}
    runs = sorted((tmp_path / "demo" / "campaign" / "runs").iterdir())
    assert [r.name for r in runs] == ["000000", "000001"]
    before = [pq.read_table(r / "measurements.parquet") for r in runs]
    assert all(t.num_rows > 0 for t in before)
    mtimes = [(r / "measurements.parquet").stat().st_mtime_ns for r in runs]
    run_demo_campaign(tmp_path / "demo", progress=False, runs=2)  # again: resumes, nothing re-run
    assert [(r / "measurements.parquet").stat().st_mtime_ns for r in runs] == mtimes
