"""The published cross-renderer checks regenerate from their committed tables alone: ``renderlab report --tables-only``
on a copy of ``crosscheck.parquet`` + ``crosscheck_images.parquet`` of each ``results/crosscheck/<scene>`` gives the
committed ``crosscheck.md`` (every number; the figure is not redrawn here: tests/test_crosscheck.py draws it); and the
page's verdicts agree with the targets applied to the table by this test itself."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from renderlab.cli import main
from renderlab.crosscheck import TARGETS

pytestmark = pytest.mark.published
REPO = Path(__file__).resolve().parents[1]
FOLDERS = sorted(p.parent for p in (REPO / "results" / "crosscheck").glob("*/crosscheck.parquet"))


def test_the_three_crosscheck_sets_are_published():
    assert [p.name for p in FOLDERS] == ["analytic_sphere_box", "ev5_low_sun", "ev5_small_descent"]


@pytest.mark.parametrize("folder", FOLDERS, ids=[p.name for p in FOLDERS])
def test_crosscheck_page_and_figure_regenerate_from_the_tables(folder, tmp_path, capsys):
    copy = tmp_path / folder.name
    copy.mkdir()
    for name in ("crosscheck.parquet", "crosscheck_images.parquet"):
        shutil.copy(folder / name, copy / name)
    assert main(["report", str(copy), "--tables-only"]) == 0
    capsys.readouterr()
    md = (folder / "crosscheck.md").read_text()
    assert (copy / "crosscheck.md").read_text() == md
    assert not (copy / "crosscheck.png").exists() and not (copy / "crosscheck.svg").exists(), "--tables-only"
    assert (folder / "crosscheck.png").stat().st_size > 50_000  # SVG only on demand (renderlab report --svg)
    assert sorted(p.name for p in folder.iterdir()) == ["crosscheck.md", "crosscheck.parquet", "crosscheck.png",
                                                         "crosscheck_images.parquet", "raw_tables.json"]
    # the images table ships what the report reads; the full one is recorded (renderlab.campaign.compact)
    raw = json.loads((folder / "raw_tables.json").read_text())["tables"]["crosscheck_images"]
    images = pq.read_table(folder / "crosscheck_images.parquet")
    assert raw["rows"] == images.num_rows and set(images.column_names) == set(raw["columns"]) - {"time_s"}
    # the verdicts of the page are the targets applied to the committed table (independent of the page's code)
    t = pq.read_table(folder / "crosscheck.parquet").to_pydict()
    worst = {k: np.nanmax(np.array(t[k], float)) for k in TARGETS}
    ok = all(worst[k] <= TARGETS[k] for k in TARGETS)
    assert ("**FAIL**" not in md) == ok
    assert f"| {worst['rad_median_rel'] * 100:.4f} % | **{'PASS' if worst['rad_median_rel'] <= 0.01 else 'FAIL'}** |" \
        in md
