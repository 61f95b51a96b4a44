"""Published study folders regenerate from their raw tables alone: ``renderlab report results/<study> --tables-only``
on a copy of the folder (tables/, campaign.json, runs.json; the committed report removed) gives the committed summary
CSVs, and its page names exactly the committed figures (the figures are not redrawn: the published tier checks
numbers; the code tier draws every kind of figure from small campaigns).

The folders directly under ``results/`` and the coastline study's nested ones (one per Monte Carlo; other studies'
nested folders have their own tests); a nested published folder is left out of its parent's copy."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest

from renderlab.campaign.publish import is_published
from renderlab.cli import main

REPO = Path(__file__).resolve().parents[1]
RESULTS = REPO / "results"
COASTLINE = ["coastline_ekf", "coastline_ekf/sensitivity_1pt_5mrad", "coastline_ekf/image_in_the_loop",
             "coastline_ekf/truth_not_model/j2_rk4", "coastline_ekf/truth_not_model/zonal_dop853"]
TRUTH_PERTURBED = ["retina_vs_spc_truth_perturbed", "retina_vs_spc_truth_perturbed/nominal"]
pytestmark = pytest.mark.published
PUBLISHED = sorted({p for p in RESULTS.iterdir() if p.is_dir() and is_published(p)}
                   | {RESULTS / c for c in COASTLINE + TRUTH_PERTURBED if is_published(RESULTS / c)})


def test_the_retina_vs_spc_study_is_published_with_its_tables():
    assert RESULTS / "retina_vs_spc" in PUBLISHED


@pytest.mark.parametrize("name", COASTLINE)
def test_every_coastline_result_folder_is_published(name):
    assert RESULTS / name in PUBLISHED
    assert sorted(p.name for p in (RESULTS / name).iterdir() if p.suffix in (".png", ".svg", ".parquet")) in (
        [], ["contact_sheet.png"]), "figures and tables live in report/ and tables/ only"


def _own_files(folder: Path):
    """``shutil.copytree`` ignore: the committed report and nested published folders."""
    def ignore(directory, names):
        d = Path(directory)
        return [n for n in names if (d == folder and n == "report") or ((d / n) != folder and is_published(d / n))]
    return ignore


@pytest.mark.parametrize("folder", PUBLISHED, ids=[p.relative_to(RESULTS).as_posix() for p in PUBLISHED])
def test_report_regenerates_from_the_published_tables(folder, tmp_path, capsys):
    copy = tmp_path / folder.name
    shutil.copytree(folder, copy, ignore=_own_files(folder))
    assert main(["report", str(copy), "--tables-only"]) == 0
    capsys.readouterr()
    committed = sorted(p.name for p in (folder / "report").glob("*.csv"))
    assert committed, "the published report has CSV tables"
    for name in committed + sorted(p.name for p in (folder / "report").glob("*.md") if p.name != "README.md"):
        assert (copy / "report" / name).read_text() == (folder / "report" / name).read_text(), name
    assert not [p for p in (copy / "report").iterdir() if p.suffix in (".png", ".svg")], "--tables-only draws none"
    figures = {p.name for p in (folder / "report").glob("*.png")}
    page = (copy / "report" / "index.html").read_text()
    assert figures and figures == set(re.findall(r'<img src="([^"]+\.png)"', page)), "the page names the figures"
    assert not list((folder / "report").glob("*.svg")) and ".svg" not in page, "PNG only; SVG with --svg"


def test_the_truth_perturbed_retina_vs_spc_campaign_is_published_beside_its_nominal_companion():
    """>= 100 runs that each moved the true pose (their own renders), and the companion with the same seeds and the
    nominal truth: the same knowledge draws run by run, no truth perturbation."""
    import pyarrow.parquet as pq

    pert = RESULTS / "retina_vs_spc_truth_perturbed"
    nom = pert / "nominal"
    assert pert in PUBLISHED and nom in PUBLISHED  # both regenerate from their tables (test above)
    p = pq.read_table(pert / "tables" / "perturbations.parquet").to_pydict()
    n = pq.read_table(nom / "tables" / "perturbations.parquet").to_pydict()
    assert len(set(p["run"])) >= 100 and len(set(n["run"])) >= 100
    assert all(abs(p[f"dpos_{a}"][k]) > 0 and abs(p[f"att_rotvec_{a}"][k]) > 0 for k in range(len(p["run"])) for a in "xyz")
    assert not any(n[f"dpos_{a}"][k] or n[f"att_rotvec_{a}"][k] for k in range(len(n["run"])) for a in "xyz")
    by_run = {r: k for k, r in enumerate(p["run"])}
    for k, r in enumerate(n["run"]):
        for c in ("focal_scale", "spacing_scale", "dpp_s", "sun_rotvec_x", "ddist_k1"):
            assert n[c][k] == p[c][by_run[r]], c
