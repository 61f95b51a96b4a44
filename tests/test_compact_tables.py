"""Compact published tables (``renderlab.campaign.compact``): the compact writer is lossless and deterministic, a
study's ``publish_tables`` decides what a published folder ships, and each full table it changes is recorded with a
SHA-256 that the real file (and ``git show`` of a committed one) reproduces.

Oracles: the numpy arrays the tables were made from (bit patterns, NaN included), ``hashlib`` over the files' bytes,
and the real ``git`` binary.
"""

from __future__ import annotations

import hashlib
import json
import subprocess

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from campaign_fixtures import SCENE, TINY

from renderlab.campaign import compact, store
from renderlab.campaign.plan import make_plan
from renderlab.campaign.publish import publish_campaign
from renderlab.campaign.runner import run_campaign
from renderlab.errors import UserError
from renderlab.scenario import load_scenario


def _table(rng, n=500):
    x = rng.normal(size=n) * 10.0 ** rng.integers(-8, 8, size=n)
    x[::37] = np.nan
    return pa.table({"run": np.repeat(np.arange(5), n // 5), "x": x, "y32": rng.normal(size=n).astype(np.float32),
                     "reason": pa.array(["ok", "no_peak"] * (n // 2)).dictionary_encode(), "kept": x > 0,
                     "img": pa.array([rng.normal(size=3).astype(np.float32) for _ in range(n)],
                                     type=pa.list_(pa.float32()))})


def test_compact_writer_is_lossless_and_deterministic(tmp_path):
    rng = np.random.default_rng(3)
    t = _table(rng)
    p = tmp_path / "t.parquet"
    compact.write_compact(t, p)
    back = pq.read_table(p)
    assert back.column_names == t.column_names
    for name in ("x", "y32"):  # bit for bit, NaN payloads included
        a, b = t[name].to_numpy(), back[name].to_numpy()
        assert a.dtype == b.dtype and a.tobytes() == b.tobytes()
    assert back["reason"].to_pylist() == t["reason"].to_pylist()
    assert back["img"].to_pylist() == t["img"].to_pylist() and back["kept"].equals(t["kept"])
    assert p.read_bytes() == compact.compact_bytes(t) == compact.compact_bytes(_table(np.random.default_rng(3)))
    meta = pq.ParquetFile(p).metadata.row_group(0)
    codecs = {meta.column(i).path_in_schema: (meta.column(i).compression, meta.column(i).encodings)
              for i in range(meta.num_columns)}
    assert codecs["x"][0] == "ZSTD" and "BYTE_STREAM_SPLIT" in codecs["x"][1]
    assert "BYTE_STREAM_SPLIT" in codecs["img.list.element"][1]


def test_keep_columns_selects_and_refuses_a_stale_reduction():
    t = _table(np.random.default_rng(0), 10)
    out = compact.keep_columns({"a": t, "b": t}, {"a": ("kept", "x")})
    assert out["a"].column_names == ["x", "kept"] and out["b"] is t  # the table's order; b untouched
    with pytest.raises(ValueError, match="lacks the published column"):
        compact.keep_columns({"a": t}, {"a": ("x", "gone")})


def _git(cwd, *args):
    return subprocess.run(["git", "-c", "user.name=t", "-c", "user.email=t@t", *args], cwd=cwd, check=True,
                          capture_output=True).stdout


def test_compact_folder_records_the_full_tables_git_can_recover(tmp_path):
    folder = tmp_path / "res" / "study"
    (folder / "tables").mkdir(parents=True)
    rng = np.random.default_rng(1)
    pq.write_table(_table(rng), folder / "tables" / "rows.parquet", compression="snappy")
    pq.write_table(pa.table({"run": [0, 1], "v": [1.0, 2.0]}), folder / "tables" / "runs.parquet")
    pq.write_table(pa.table({"n": [1]}), folder / "tables" / "scratch.parquet")
    originals = {p.stem: p.read_bytes() for p in (folder / "tables").glob("*.parquet")}
    _git(tmp_path, "init", "-q")
    _git(tmp_path, "add", ".")
    _git(tmp_path, "commit", "-qm", "full")

    def reduce(tables):
        out = compact.keep_columns(tables, {"rows": ("run", "x")})
        del out["scratch"]
        return out

    sizes = compact.compact_folder(folder, reduce, command="renderlab campaign s.toml")
    assert sizes["scratch"][1] is None and not (folder / "tables" / "scratch.parquet").exists()
    assert sizes["rows"][1] < sizes["rows"][0]
    rec = json.loads((folder / "tables" / compact.RAW_TABLES).read_text())
    assert rec["format"] == compact.RAW_FORMAT and sorted(rec["tables"]) == ["rows", "scratch"]  # runs: unchanged
    for name, r in rec["tables"].items():
        assert r["sha256"] == hashlib.sha256(originals[name]).hexdigest() and r["bytes"] == len(originals[name])
        assert r["regenerate"] == "renderlab campaign s.toml"
        cmd = r["recover"].split()
        assert cmd[:2] == ["git", "show"] and ":res/study/tables/" in cmd[2]
        assert hashlib.sha256(_git(tmp_path, *cmd[1:])).hexdigest() == r["sha256"]  # real git gives the file back
    assert rec["tables"]["rows"]["columns"] == ["run", "x", "y32", "reason", "kept", "img"]
    assert pq.read_table(folder / "tables" / "rows.parquet").column_names == ["run", "x"]
    assert pq.read_table(folder / "tables" / "runs.parquet").equals(pa.table({"run": [0, 1], "v": [1.0, 2.0]}))
    assert not list((folder / "tables").glob(".*")), "no staged file is left"
    # a second reduction keeps the record of the original, not of the already reduced table
    compact.compact_folder(folder, lambda t: compact.keep_columns(t, {"rows": ("x",)}))
    again = json.loads((folder / "tables" / compact.RAW_TABLES).read_text())
    assert again["tables"]["rows"] == rec["tables"]["rows"]


def _values_study(scenario, base_dir, run_index, seed_sequence, workdir):
    rng = np.random.default_rng(seed_sequence)
    return {"values": pa.table({"x": rng.normal(size=4), "noise": rng.normal(size=4)})}


def test_publish_applies_the_study_reduction(tmp_path):
    from renderlab import plugins
    from renderlab.contracts.study import Study

    plugins.studies.register("compacting", Study(name="compacting", run=_values_study, worlds=("analytic",),
                                                 publish_tables=lambda t: compact.keep_columns(t, {"values": ("x",)})))
    try:
        sc, base = load_scenario(SCENE, TINY)
        run_campaign(make_plan(sc, base, runs=2, seed=4, study="compacting"), tmp_path / "c", progress=False)
        full = store.load_tables(tmp_path / "c")["values"]
        publish_campaign(tmp_path / "c", tmp_path / "pub")
    finally:
        plugins.studies.unregister("compacting")
    tdir = tmp_path / "pub" / "tables"
    shipped = pq.read_table(tdir / "values.parquet")
    assert shipped.column_names == ["x"] and shipped["x"].equals(full["x"])
    rec = json.loads((tdir / compact.RAW_TABLES).read_text())["tables"]["values"]
    assert rec["rows"] == full.num_rows == 8 and "noise" in rec["columns"]
    assert rec["sha256"] == hashlib.sha256(compact.compact_bytes(full)).hexdigest()


def test_a_corrupt_record_is_one_line(tmp_path):
    (tmp_path / compact.RAW_TABLES).write_text("{not json")
    with pytest.raises(UserError, match="raw_tables.json: not readable JSON"):
        compact.read_raw_tables(tmp_path)
    (tmp_path / compact.RAW_TABLES).write_text(json.dumps({"format": "x", "tables": {}}))
    with pytest.raises(UserError, match="not a renderlab.raw_tables/1 record"):
        compact.read_raw_tables(tmp_path)



def test_replacing_write_leaves_the_old_table_whole_when_it_fails(tmp_path):
    from renderlab.files.parquet_compact import write_compact_replacing

    t = _table(np.random.default_rng(2), 20)
    p = tmp_path / "t.parquet"
    write_compact_replacing(t, p)
    assert p.read_bytes() == compact.compact_bytes(t) and [q.name for q in tmp_path.iterdir()] == ["t.parquet"]
    with pytest.raises(AttributeError):  # not a table: nothing is written
        write_compact_replacing(object(), p)
    assert p.read_bytes() == compact.compact_bytes(t) and [q.name for q in tmp_path.iterdir()] == ["t.parquet"]


def test_recovery_runs_only_a_git_show_of_a_recorded_commit(tmp_path):
    rec = {"sha256": "0" * 64, "bytes": 1, "rows": 1, "columns": ["x"], "regenerate": "-",
           "recover": f"touch {tmp_path / 'ran'}"}
    (tmp_path / compact.RAW_TABLES).write_text(compact.raw_tables_json({"t": rec}))
    assert compact.recover_raw_table(tmp_path, "t") is None and not (tmp_path / "ran").exists()
