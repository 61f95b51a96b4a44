"""``renderlab publish`` writes a campaign's raw tables as a study folder, and ``renderlab report`` regenerates the
same summary from that folder alone (no runs/, no re-run)."""

from __future__ import annotations

import shutil

import pyarrow.parquet as pq
from campaign_fixtures import SCENE, TINY

from renderlab.cli import main


def test_publish_then_report_from_tables_alone(tmp_path, capsys):
    camp, res = tmp_path / "camp", tmp_path / "results" / "study"
    args = ["campaign", str(SCENE), "--runs", "3", "--out", str(camp), "--workers", "0", "--quiet", "--seed", "4",
            *[a for kv in TINY for a in ("--set", kv)]]
    assert main(args) == 0
    assert main(["report", str(camp), "--out", str(tmp_path / "rep")]) == 0
    assert main(["publish", str(camp), "--out", str(res)]) == 0
    capsys.readouterr()
    assert sorted(p.name for p in res.iterdir()) == ["campaign.json", "report", "runs.json", "tables"]
    assert pq.read_table(res / "tables" / "measurements.parquet").num_rows == \
        sum(pq.read_table(p).num_rows for p in camp.glob("runs/*/measurements.parquet"))
    shutil.rmtree(camp)  # the published folder must stand alone
    (res / "report" / "summary.csv").unlink()
    assert main(["report", str(res)]) == 0
    assert (res / "report" / "summary.csv").read_text() == (tmp_path / "rep" / "summary.csv").read_text()
    assert main(["report", str(tmp_path / "rep")]) == 2 and "--out DIR is needed" in capsys.readouterr().err
