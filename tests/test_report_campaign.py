"""``renderlab report``: summary.csv equals statistics computed directly from the runs' Parquet files
with numpy/scipy; the HTML page links every figure, and every figure is a readable PNG."""

from __future__ import annotations

import csv
import re

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
from campaign_fixtures import SCENE, TINY
from scipy import stats

from renderlab.cli import main


def test_report_from_tables(tmp_path, capsys):
    import cv2

    camp = tmp_path / "camp"
    args = ["campaign", str(SCENE), "--runs", "4", "--out", str(camp), "--workers", "0", "--quiet", "--seed", "2",
            *[a for kv in TINY for a in ("--set", kv)]]
    assert main(args) == 0
    assert main(["report", str(camp), "--out", str(tmp_path / "rep")]) == 0
    rep = tmp_path / "rep"
    t = pa.concat_tables([pq.read_table(p) for p in sorted(camp.glob("runs/*/measurements.parquet"))])
    rows = list(csv.DictReader((rep / "summary.csv").open()))
    assert {(r["subset"], r["method"], r["axis"]) for r in rows} == {("all", m, a) for m in ("centroid", "ellipse")
                                                                       for a in "sl"}
    for r in rows:
        sel = np.array(t.column("method").to_pylist()) == r["method"]
        e = np.array(t.column(f"err_{r['axis']}").to_pylist(), float)[sel]
        has = np.array(t.column("has_result").to_pylist(), bool)[sel]
        good = e[has]
        good = good[np.isfinite(good)]
        assert int(r["n_rows"]) == sel.sum() and int(r["n_result"]) == len(good)
        assert abs(float(r["no_result_rate"]) - (1 - len(good) / sel.sum())) < 1e-5
        if len(good) >= 2:
            assert abs(float(r["bias_px"]) - good.mean()) <= 1e-5 * max(1, abs(good.mean()))
            assert abs(float(r["std_px"]) - good.std(ddof=1)) <= 1e-5 * max(1, good.std())
            assert abs(float(r["robust_sigma_px"]) - stats.median_abs_deviation(good, scale="normal")) <= 1e-5
            assert float(r["bias_px_lo"]) <= float(r["bias_px"]) <= float(r["bias_px_hi"])
    page = (rep / "index.html").read_text()
    imgs = re.findall(r'src="([^"]+\.png)"', page)
    assert not re.findall(r'href="([^"]+\.svg)"', page) and not list(rep.glob("*.svg")), "SVG only with --svg"
    assert len(imgs) >= 3 and any("fig12" in n for n in imgs)  # the no-result figure only when a row has none
    for name in imgs:
        img = cv2.imread(str(rep / name))
        assert img is not None and img.shape[0] > 100 and img.std() > 0
    assert "renderlab report camp --out rep" in page and "cluster bootstrap" in page
    assert (rep / "measurements_breakdown.csv").is_file() and (rep / "summary.csv").is_file()
    assert main(["report", str(tmp_path / "nowhere"), "--out", str(rep)]) == 2
    assert "not a campaign folder" in capsys.readouterr().err
    # --svg: an SVG beside every PNG, linked from its caption; the PNGs the same bytes as without it
    assert main(["report", str(camp), "--out", str(tmp_path / "rep_svg"), "--svg"]) == 0
    page_svg = (tmp_path / "rep_svg" / "index.html").read_text()
    svgs = re.findall(r'href="([^"]+\.svg)"', page_svg)
    assert sorted(svgs) == sorted(n.replace(".png", ".svg") for n in imgs)
    assert all((tmp_path / "rep_svg" / n).read_text().lstrip().startswith("<?xml") for n in svgs)
    assert all((tmp_path / "rep_svg" / n).read_bytes() == (rep / n).read_bytes() for n in imgs)
    capsys.readouterr()
    assert main(["report", str(camp), "--out", str(tmp_path / "rep_x"), "--svg", "--tables-only"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--svg" in err and not (tmp_path / "rep_x").exists()
