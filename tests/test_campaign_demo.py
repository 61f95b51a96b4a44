"""``renderlab demo`` end to end (``run_demo`` once, every campaign at 2 runs): the Retina-vs-SPC campaign
(real render, both methods, report, resume) the demo opens with; and the coastline-EKF and unknown-satellite
sections of ``report.md`` — every link resolves, and the numbers printed are the campaigns' own tables
(coastline steady state, unknown-satellite scores) from estimators that work (‖ω0‖ within 4σ of the CRLB,
FIM rank deficient by the inertia scale only)."""

from __future__ import annotations

import csv
import re
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    """``run_demo`` once for the module, every campaign at 2 runs (the real renders, estimators, reports)."""
    from renderlab.commands.demo import run_demo

    out = tmp_path_factory.mktemp("demo") / "demo_out"
    report, html = run_demo(out, progress=False, runs=(2, 2, 2))
    return out, report, html


def test_demo_campaign_writes_report_with_both_methods_and_resumes(demo):
    from renderlab.studies.retina_vs_spc.demo import run_demo_campaign

    out, _, html = demo
    assert html == out / "campaign" / "report" / "index.html" and html.is_file()   # the demo opens with it
    rows = list(csv.DictReader((html.parent / "summary.csv").open()))
    assert {r["method"] for r in rows} >= {"retina", "spc"}
    runs = sorted((out / "campaign" / "campaign" / "runs").iterdir())
    assert [r.name for r in runs] == ["000000", "000001"]
    before = [pq.read_table(r / "measurements.parquet") for r in runs]
    assert all(t.num_rows > 0 for t in before)
    mtimes = [(r / "measurements.parquet").stat().st_mtime_ns for r in runs]
    assert run_demo_campaign(out / "campaign", progress=False, runs=2) == html  # again: resumes, nothing re-run
    assert [(r / "measurements.parquet").stat().st_mtime_ns for r in runs] == mtimes


def _section(text: str, title: str) -> str:
    return text.split(f"## {title}", 1)[1].split("\n## ", 1)[0]


def test_demo_runs_coastline_and_unknown_satellite_campaigns(demo):
    from renderlab.campaign.store import load_tables

    out, report, _ = demo
    text = report.read_text(encoding="utf-8")
    links = re.findall(r"\]\(([^)\s]+)\)", text)
    assert links and all((out / link).is_file() for link in links), [x for x in links if not (out / x).is_file()]
    assert all((out / x).stat().st_size > 5000 for x in links if x.endswith(".png"))

    co = _section(text, "Campaign: coastline-matching EKF")
    assert "2 seeded runs" in co and "0 failed" in co and "coastline/coastline_report/index.html" in co
    with open(out / "coastline" / "coastline_report" / "coastline_filter_coastline_steady_state.csv") as f:
        ss = next(csv.DictReader(f))
    for name, k, fm in (("radial position (m)", "r_m", "{:.1f}"), ("cross-track velocity (m/s)", "vc_mps", "{:.3f}")):
        mc, filt = float(ss[f"mc_3sig_{k}"]), float(ss[f"filter_3sig_{k}"])
        assert mc > 0 and filt > 0                                  # a filter that ran, not an empty table
        assert f"| {name} | {fm.format(mc)} | {fm.format(filt)} |" in co
    assert f"NIS/dof {float(ss['nis_total_over_dof']):.3f}" in co

    us = _section(text, "Campaign: unknown tumbling satellite")
    assert "2 runs" in us and "0 failed" in us and "unknown_satellite/report/index.html" in us
    sc = load_tables(out / "unknown_satellite" / "campaign")["scores"].to_pydict()
    assert sorted(sc["run"]) == [0, 1]

    def med(key, scale=1.0):
        return float(np.median(sc[key]) * scale)
    assert (f"| {med('point_lvlh_err_rms_m', 100):.1f} (CRLB σ {med('point_lvlh_crlb_rms_m', 100):.1f}) |") in us
    assert f"| {med('w0_norm_est_deg_s'):.3f} / {med('w0_norm_true_deg_s'):.3f} " in us
    assert f"| {med('stage2_vel_rms_mps', 100):.2f} |" in us
    # what the section reports is a working estimator: ‖ω0‖ within 4σ of its CRLB in every run, and the
    # Fisher matrix of eq. 7 deficient by the inertia scale only
    for err, sig in zip(sc["w0_norm_err_deg_s"], sc["w0_norm_crlb_deg_s"]):
        assert abs(err) < 4 * sig < 0.2, (err, sig)
    assert set(np.subtract(sc["fim_params"], sc["fim_rank"])) == {1}
    assert f"| {min(sc['fim_rank'])} of {max(sc['fim_params'])} (the inertia scale is not observable)" in us
    figs = {x.rsplit("/", 1)[-1] for x in re.findall(r"\]\(([^)\s]+\.png)\)", us)}
    assert {f"unknown_satellite_{f}.png" for f in ("fig5_convergence", "fig6_inertia", "fig7_points",
                                                   "fig13_stage2_position", "fig14_stage2_attitude")} <= figs
    page = (out / "unknown_satellite" / "report" / "index.html").read_text(encoding="utf-8")
    assert "Unknown satellite: scores and figures" in page


@pytest.mark.parametrize("page", ["campaign/report/index.html", "coastline/coastline_report/index.html",
                                  "unknown_satellite/report/index.html"])
def test_demo_reports_open_in_a_real_browser(demo, page):
    """Every study's report of the demo opens in headless Chromium with every image loaded and no broken link;
    a full-page screenshot goes to tests/artifacts/ (what a reader sees first)."""
    import os

    from browser import check_report, find_chromium, screenshot

    if find_chromium() is None:
        if os.environ.get("CI", "").lower() in ("1", "true", "yes"):
            pytest.fail("chromium is required in CI (.ci/run installs Debian's chromium)")
        pytest.skip("chromium not installed (apt-get install chromium)")
    out, _, _ = demo
    html = out / page
    assert html.is_file(), page
    problems = check_report(html)
    assert problems == [], problems
    art = Path(__file__).parent / "artifacts"
    art.mkdir(exist_ok=True)
    shot = art / f"demo_{page.split('/')[0]}_report.png"
    screenshot(html, shot, width=1280, height=3000)
    assert shot.is_file() and shot.stat().st_size > 10_000
