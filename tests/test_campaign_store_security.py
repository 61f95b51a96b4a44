"""Campaign files are data, validated like scenarios: table names are plain names inside the run folder (no path
traversal), ``plan.runs`` is bounded, ``plan.study`` resolves only through the registry, corrupt Parquet is a
one-line error. Each case fails on the code before the fix (report read ``../x.parquet``; runs = 10**12 looped)."""

from __future__ import annotations

import json
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from renderlab.cli import main

REPO = Path(__file__).resolve().parents[1]
SCENE = REPO / "scenes" / "analytic_sphere_box.toml"


@pytest.fixture()
def camp(tmp_path):
    from renderlab.campaign import store
    from renderlab.campaign.plan import make_plan
    from renderlab.scenario import load_scenario

    sc, base = load_scenario(SCENE)
    plan = make_plan(sc, base, runs=1)
    d = tmp_path / "camp"
    store.open_campaign(d, plan, resume=False)
    store.write_run(d, 0, {"values": pa.table({"x": [1.0]})}, {"run": 0, "status": "ok", "error": "", "seconds": 0.0})
    return d


def _tamper(path: Path, **changes):
    data = json.loads(path.read_text())
    for k, v in changes.items():
        cur = data
        *head, last = k.split(".")
        for h in head:
            cur = cur[h]
        cur[last] = v
    path.write_text(json.dumps(data))


def _refused(capsys, argv, needle):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("renderlab: error:") and err.count("\n") == 1 and needle in err, err


def test_table_name_with_a_path_is_refused(camp, tmp_path, capsys):
    outside = tmp_path / "outside.parquet"
    pq.write_table(pa.table({"err_s": [0.0]}), outside)
    _tamper(camp / "runs" / "000000" / "status.json", tables=["../../../outside"])
    _refused(capsys, ["report", str(camp), "--out", str(tmp_path / "rep")], "plain table names")
    assert not (tmp_path / "rep").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["camp", "outside.parquet"]


def test_huge_or_bad_run_count_is_refused(camp, tmp_path, capsys):
    _tamper(camp / "campaign.json", **{"plan.runs": 10**12})
    _refused(capsys, ["report", str(camp), "--out", str(tmp_path / "rep")], "plan.runs: must be less than or equal to 1000000")
    _tamper(camp / "campaign.json", **{"plan.runs": True})
    _refused(capsys, ["report", str(camp), "--out", str(tmp_path / "rep")], "plan.runs: must be a valid integer")


def test_study_naming_a_module_is_never_imported(camp, tmp_path, capsys):
    _tamper(camp / "campaign.json", **{"plan.study": "os:getcwd"})
    assert main(["report", str(camp), "--out", str(tmp_path / "rep")]) == 0  # report: no study sections, no import
    capsys.readouterr()
    _refused(capsys, ["campaign", str(SCENE), "--runs", "1", "--out", str(tmp_path / "c2"), "--workers", "0",
                      "--set", "campaign.study=os:getcwd"], "unknown study 'os:getcwd'")
    assert not (tmp_path / "c2").exists()


def test_corrupt_parquet_is_one_line(camp, tmp_path, capsys):
    (camp / "runs" / "000000" / "values.parquet").write_bytes(b"PAR1 not really")
    _refused(capsys, ["report", str(camp), "--out", str(tmp_path / "rep")], "cannot read")
