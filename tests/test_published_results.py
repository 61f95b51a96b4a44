"""Published study folders regenerate from their raw tables alone: ``renderlab report results/<study>`` on a copy of
the folder (tables/, campaign.json, runs.json; the committed report removed) gives the committed summary CSVs."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from renderlab.campaign.publish import is_published
from renderlab.cli import main

REPO = Path(__file__).resolve().parents[1]
PUBLISHED = sorted(p for p in (REPO / "results").iterdir() if p.is_dir() and is_published(p))


def test_the_retina_vs_spc_study_is_published_with_its_tables():
    assert REPO / "results" / "retina_vs_spc" in PUBLISHED


@pytest.mark.parametrize("folder", PUBLISHED, ids=[p.name for p in PUBLISHED])
def test_report_regenerates_from_the_published_tables(folder, tmp_path, capsys):
    copy = tmp_path / folder.name
    shutil.copytree(folder, copy, ignore=shutil.ignore_patterns("report"))
    assert main(["report", str(copy)]) == 0
    capsys.readouterr()
    committed = sorted(p.name for p in (folder / "report").glob("*.csv"))
    assert committed, "the published report has CSV tables"
    for name in committed:
        assert (copy / "report" / name).read_text() == (folder / "report" / name).read_text(), name
    figures = {p.name for p in (folder / "report").glob("*.png")}
    assert figures and figures == {p.name for p in (copy / "report").glob("*.png")}
