"""The published unknown-satellite campaigns (Ivanov et al. 2018) regenerate from their committed tables alone.

``results/unknown_satellite/campaign_30s`` (20 runs, 30 s arc) and ``long_arc_120s`` (8 runs, 120 s arc, with the
Fisher-information table ``inertia_observability``) are published study folders: ``renderlab report --tables-only``
on a copy of their tables/, campaign.json and runs.json gives the committed summary CSVs (every number) and a page
that names the committed figures (PNG; not redrawn here, tests/test_unknown_satellite_campaign.py draws them);
no figure, table or script lies outside tables/ and report/. On the 20-run tables the study section
reports score ids in the unit of their values, flags as a rate with "k of 20", and explains the large stage-2
attitude error (it follows the stage-1 epoch attitude; unobservable inertia ratios).
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest

from renderlab.campaign.publish import is_published, load_published_tables
from renderlab.cli import main

pytestmark = pytest.mark.published
REPO = Path(__file__).resolve().parents[1]
HERE = REPO / "results" / "unknown_satellite"
FOLDERS = [HERE / "campaign_30s", HERE / "long_arc_120s"]


def test_the_study_publishes_two_folders_and_nothing_else():
    assert all(is_published(f) for f in FOLDERS)
    loose = [p.relative_to(HERE).as_posix() for p in HERE.rglob("*") if p.is_file()
             and p.suffix in (".png", ".svg", ".parquet", ".py", ".csv", ".json")
             and not any(part in ("tables", "report") for part in p.relative_to(HERE).parts)
             and p.name not in ("campaign.json", "runs.json")]
    assert loose == [], "figures, tables and scripts live in a published folder's tables/ and report/ only"


@pytest.mark.parametrize("folder", FOLDERS, ids=[f.name for f in FOLDERS])
def test_report_regenerates_from_the_published_tables(folder, tmp_path, capsys):
    copy = tmp_path / folder.name
    shutil.copytree(folder, copy, ignore=shutil.ignore_patterns("report", "README.md"))
    assert main(["report", str(copy), "--tables-only"]) == 0
    capsys.readouterr()
    csvs = sorted(p.name for p in (folder / "report").glob("*.csv"))
    assert "unknown_satellite_summary.csv" in csvs
    for name in csvs:
        assert (copy / "report" / name).read_text() == (folder / "report" / name).read_text(), name
    pngs = {p.name for p in (folder / "report").glob("*.png")}
    assert not [p for p in (copy / "report").iterdir() if p.suffix in (".png", ".svg")], "--tables-only draws none"
    assert pngs == set(re.findall(r'<img src="([^"]+\.png)"', (copy / "report" / "index.html").read_text()))
    assert not list((folder / "report").glob("*.svg")), "PNG only; SVG with renderlab report --svg"
    assert "summary.csv" not in csvs, "the summary is written once, as unknown_satellite_summary.csv"
    want = {f"unknown_satellite_{f}.png" for f in ("fig5_convergence", "fig6_inertia", "fig7_points",
                                                   "fig13_stage2_position", "fig14_stage2_attitude")}
    if folder.name == "long_arc_120s":
        want.add("unknown_satellite_inertia_sigma_vs_arc.png")
    assert pngs == want


def test_report_section_on_the_published_campaign(tmp_path):
    """Score ids carry the unit of their values, flags are a rate with "k of 20", the large stage-2 attitude error
    is explained, raw and relabelled rows are both shown because some runs came out relabelled."""
    from renderlab.studies.unknown_satellite.figures import SCORES, same_pairs, score_summary
    from renderlab.studies.unknown_satellite.report_section import study_section

    tables = load_published_tables(HERE / "campaign_30s")
    units = {"cm": ("_cm",), "cm/s": ("_cm_s",), "deg/s": ("_deg_s",), "deg": ("_deg",), "px": ("_px",)}
    flags = {}
    for r in score_summary(tables["scores"]):
        if r["unit"] in units:
            assert r["score"].endswith(units[r["unit"]]), r
        if r["score"].startswith("flag_"):
            assert "mean" not in r and 0 <= r["flagged"] <= r["runs"] == 20
            assert r["rate"] == r["flagged"] / 20
            flags[r["score"][5:]] = r["flagged"]
    assert all(v[0] != c or not c.endswith(("_m", "_mps")) for c, v in SCORES.items())
    assert same_pairs(tables["scores"]) == set() and flags["axes_relabelled"] > 0
    [(_, body)] = study_section(tables, tmp_path)
    k = flags["not_converged"]
    assert f"<td class=\"\">{100 * k / 20:.0f} %</td><td class=\"\">{k} of 20</td>" in body
    assert f"{flags['axes_relabelled']} of 20 runs came out relabelled" in body
    assert "follows the stage-1 epoch attitude error" in body and "not observable on this arc" in body
    assert "_aligned" not in body and "×10" not in body
