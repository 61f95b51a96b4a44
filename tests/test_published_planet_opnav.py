"""The published planet OpNav campaign (``results/planet_opnav``) regenerates from its committed table alone, covers
the grid and methods it claims, and its README's numbers are the table's.

``renderlab report --tables-only`` on a copy of tables/, campaign.json and runs.json gives every committed CSV byte for
byte and a page naming the committed PNGs; the README's results table is recomputed here from the committed table by
the kind's scorer; the zero-phase half-pixel offset of ``bsk_limb_horizon`` the README reports is checked per cell.
"""

from __future__ import annotations

import math
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from renderlab.campaign.publish import is_published, load_published_tables
from renderlab.cli import main

pytestmark = pytest.mark.published
FOLDER = Path(__file__).resolve().parents[1] / "results" / "planet_opnav"
LAB = {"centroid_raw", "centroid_phase", "limb_ellipse", "horizon_opnav"}
BSK = {"bsk_hough_circles", "bsk_hough_pixel_line", "bsk_limb_horizon"}


def test_the_folder_is_published_small_and_complete():
    assert is_published(FOLDER)
    files = [p for p in FOLDER.rglob("*") if p.is_file()]
    assert sum(p.stat().st_size for p in files) <= 3_000_000
    assert max(p.stat().st_size for p in files) <= 1_000_000
    assert not [p for p in files if p.suffix in (".svg", ".py")]
    loose = {p.relative_to(FOLDER).as_posix() for p in files if p.parent == FOLDER}
    assert loose == {"README.md", "scenario.toml", "campaign.json", "runs.json"}


def test_the_table_covers_the_grid_and_methods_on_the_same_images():
    d = load_published_tables(FOLDER)["centre_limb"].to_pandas()
    assert d.range_nominal_m.nunique() >= 4 and d.phase_nominal_deg.nunique() >= 7 and d.law.nunique() == 2
    assert set(d.method) == LAB | BSK and d.run.nunique() >= 8
    assert (d.groupby(["law", "range_nominal_m", "phase_nominal_deg"]).cell.nunique() == 1).all()
    same = d.groupby(["run", "cell"]).agg(n=("method", "size"), s=("true_centre_s", "nunique"),
                                          r=("true_range_m", "nunique"))
    assert (same.n == 7).all() and (same.s == 1).all() and (same.r == 1).all()


def test_report_regenerates_from_the_published_tables(tmp_path, capsys):
    copy = tmp_path / "planet_opnav"
    shutil.copytree(FOLDER, copy, ignore=shutil.ignore_patterns("report", "README.md"))
    assert main(["report", str(copy), "--tables-only"]) == 0
    capsys.readouterr()
    csvs = sorted(p.name for p in (FOLDER / "report").glob("*.csv"))
    assert set(csvs) == {"centre_limb_summary.csv", "centre_limb_cells.csv"}   # no summary.csv copy of the first
    for name in csvs:
        assert (copy / "report" / name).read_text() == (FOLDER / "report" / name).read_text(), name
    pngs = {p.name for p in (FOLDER / "report").glob("*.png")}
    assert pngs == {"centre_limb_bias.png", "centre_limb_nees.png"}
    assert pngs == set(re.findall(r'<img src="([^"]+\.png)"', (copy / "report" / "index.html").read_text()))


def _ci(r, scale=1.0, d=2):
    e, lo, hi = (r[k] * scale for k in ("estimate", "lo", "hi"))
    return "–" if not math.isfinite(e) else f"{e:+.{d}f} [{lo:+.{d}f}, {hi:+.{d}f}]"


def _g(r, scale=1.0):
    e, lo, hi = (r[k] * scale for k in ("estimate", "lo", "hi"))
    return "–" if not math.isfinite(e) else f"{e:.3g} [{lo:.3g}, {hi:.3g}]"


def test_readme_results_table_is_the_tables():
    from renderlab.stats.centre_limb import score_table

    rows = score_table(load_published_tables(FOLDER)["centre_limb"])
    q = {(r["method"], r["quantity"]): r for r in rows if r["group"] == "all"}
    text = (FOLDER / "README.md").read_text(encoding="utf-8")
    for m in sorted(LAB | BSK):
        a = q[(m, "anees_centre")]
        want = (f"| {m} | {_ci(q[(m, 'bias_s')])}, {_ci(q[(m, 'bias_l')])} | {_g(q[(m, 'noise_s')])}, "
                f"{_g(q[(m, 'noise_l')])} | {_g(q[(m, 'los_rms_urad')])} | {_ci(q[(m, 'bias_range_rel')], 100)} | "
                f"{_g(q[(m, 'noise_range_rel')], 100)} | {a['estimate']:.3g} ([{a['band_lo']:.3g}, "
                f"{a['band_hi']:.3g}]) {'PASS' if a['inside'] else 'FAIL'} | {_g(q[(m, 'median_nees_centre')])} |")
        assert want in text, want


def test_the_half_pixel_finding_holds_in_every_zero_phase_cell():
    import pandas as pd

    c = pd.read_csv(FOLDER / "report" / "centre_limb_cells.csv")
    z = c[(c.method == "bsk_limb_horizon") & (c.phase_deg < 0.5)]
    assert len(z) == 8
    assert np.all(np.abs(z[["bias_s_px", "bias_l_px"]].to_numpy() + 0.5) < 0.06)
    lab = c[(c.method == "horizon_opnav") & (c.phase_deg < 0.5)]
    assert np.all(np.abs(lab[["bias_s_px", "bias_l_px"]].to_numpy()) < 0.05)   # the same images, no offset
