"""Compact published tables: a folder ships the tables its report reads, and only those; the full tables are recorded.

The results policy (docs/results_policy.md): a published folder holds the tables its report reads, at full
precision — no float downcast, no rounding, so every published number follows from them unchanged. What the report
never reads (raw columns, per-row detail it only uses through an aggregate) is left out, and ``tables/
raw_tables.json`` records each full table so that it can be found again and checked: its SHA-256, bytes, rows and
columns, where it can be recovered (``git show <commit>:<path>`` for a folder that was committed whole) and the
command that regenerates it (the campaign command of the folder's README).

A study says what it publishes with :attr:`renderlab.contracts.study.Study.publish_tables`, a pure function
``{name: table} -> {name: table}`` (:func:`keep_columns` for the common case); ``renderlab publish`` applies it
(:mod:`renderlab.campaign.publish`). A folder published before is compacted in place with :func:`compact_folder`::

    python -m renderlab.campaign.compact results/FOLDER [--command "renderlab campaign ..."]

Every table is written by :func:`write_compact`: zstd level 19, byte-stream-split floating columns, dictionary
encoding for the others; the same table gives the same bytes.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import re
import secrets
import subprocess
import sys
from pathlib import Path
from typing import Callable, Mapping, Sequence

from renderlab.errors import UserError
from renderlab.files.parquet_compact import ZSTD_LEVEL, compact_bytes, write_compact  # noqa: F401  (re-exported)

#: the record of the full tables, inside a folder's tables directory
RAW_TABLES = "raw_tables.json"
RAW_FORMAT = "renderlab.raw_tables/1"

Tables = Mapping[str, "object"]  # name -> pyarrow.Table


def keep_columns(tables: Tables, keep: Mapping[str, Sequence[str]]) -> dict:
    """``tables`` with only the columns ``keep`` names for each table (in the table's own order); a table ``keep``
    does not name is kept whole. A column named but absent raises ``ValueError`` (the reduction is out of date)."""
    out = {}
    for name, t in tables.items():
        cols = keep.get(name)
        if cols is None:
            out[name] = t
            continue
        missing = [c for c in cols if c not in t.column_names]
        if missing:
            raise ValueError(f"table {name!r} lacks the published column(s) {missing}")
        out[name] = t.select([c for c in t.column_names if c in set(cols)])
    return out


def raw_record(table, file_bytes: bytes, *, recover: str | None, regenerate: str) -> dict:
    """The ``raw_tables.json`` entry of one full table (``file_bytes``: the file it was, or would be, written as)."""
    return {"sha256": hashlib.sha256(file_bytes).hexdigest(), "bytes": len(file_bytes), "rows": table.num_rows,
            "columns": list(table.column_names), "recover": recover, "regenerate": regenerate}


def read_raw_tables(tables_dir: Path) -> dict:
    """``{name: record}`` of ``tables_dir/raw_tables.json`` ({} when there is none)."""
    p = Path(tables_dir) / RAW_TABLES
    if not p.is_file():
        return {}
    try:
        doc = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise UserError(f"{p.name}: not readable JSON ({exc})") from None
    if not isinstance(doc, dict) or doc.get("format") != RAW_FORMAT or not isinstance(doc.get("tables"), dict):
        raise UserError(f"{p.name}: not a {RAW_FORMAT} record")
    return doc["tables"]


def recover_raw_table(tables_dir: Path, name: str):
    """The full table ``name`` recorded in ``tables_dir/raw_tables.json``, read back by its ``git show`` and
    checked against its SHA-256 (a pyarrow Table); None where this checkout cannot recover it (no git history)."""
    import io

    import pyarrow.parquet as pq

    rec = read_raw_tables(tables_dir).get(name)
    spec = re.fullmatch(r"git show ([0-9a-f]{40}:[\w./-]+\.parquet)", str((rec or {}).get("recover") or ""))
    if spec is None:  # only the form _git_recover writes is run: a data file never names a command
        return None
    got = subprocess.run(["git", "show", spec.group(1)], cwd=Path(tables_dir), capture_output=True)
    if got.returncode or hashlib.sha256(got.stdout).hexdigest() != rec["sha256"]:
        return None
    return pq.read_table(io.BytesIO(got.stdout))


def raw_tables_json(records: Mapping[str, dict]) -> str:
    return json.dumps({"format": RAW_FORMAT, "tables": dict(sorted(records.items()))}, indent=1) + "\n"


def _same(a, b) -> bool:
    return a.column_names == b.column_names and a.num_rows == b.num_rows and a.equals(b)


def _git_recover(path: Path) -> str | None:
    """``git show <HEAD>:<path>`` when ``path`` is tracked and unmodified at HEAD, else None."""
    def git(*args):
        return subprocess.run(["git", *args], cwd=path.parent, capture_output=True, text=True)

    top = git("rev-parse", "--show-toplevel")
    head = git("rev-parse", "HEAD")
    if top.returncode or head.returncode:
        return None
    rel = Path(os.path.relpath(path.resolve(), Path(top.stdout.strip()).resolve())).as_posix()
    tracked = git("ls-files", "--error-unmatch", "--", path.name).returncode == 0
    clean = git("diff", "--quiet", "HEAD", "--", path.name).returncode == 0
    return f"git show {head.stdout.strip()}:{rel}" if tracked and clean else None


def compact_folder(folder, transform: Callable[[dict], dict] | None = None, *, tables_dir: str = "tables",
                   command: str = "the campaign command of README.md, then renderlab publish") -> dict:
    """Reduce the tables of one published folder in place (module docstring); returns ``{name: (old, new) bytes}``.

    Every ``*.parquet`` of ``folder/tables_dir`` is read, ``transform`` (default: none) maps them to the tables to
    publish, and each is rewritten by :func:`write_compact`; each table that ``transform`` changed or dropped is
    recorded in ``raw_tables.json`` (an earlier record of the same table is kept: it describes the original).
    The new files are written beside the old ones under hidden names and moved into place only once all are written.
    """
    import pyarrow.parquet as pq

    tdir = Path(folder) / tables_dir
    paths = {p.stem: p for p in sorted(tdir.glob("*.parquet"))}
    if not paths:
        raise UserError(f"{tdir}: no Parquet tables to compact")
    old = {name: pq.read_table(os.fspath(p)) for name, p in paths.items()}
    new = dict(transform(dict(old)) if transform else old)
    records = read_raw_tables(tdir)
    for name, t in old.items():
        if name in records or (name in new and _same(t, new[name])):
            continue
        records[name] = raw_record(t, paths[name].read_bytes(), recover=_git_recover(paths[name]),
                                   regenerate=command)
    token = secrets.token_hex(4)
    staged = {}
    try:
        for name, t in sorted(new.items()):
            staged[name] = tdir / f".{name}.compact-{token}.parquet"
            write_compact(t, staged[name])
        raw_stage = tdir / f".{RAW_TABLES}.{token}"
        raw_stage.write_text(raw_tables_json(records), encoding="utf-8")
    except BaseException:
        for p in [*staged.values(), tdir / f".{RAW_TABLES}.{token}"]:
            p.unlink(missing_ok=True)
        raise
    sizes = {name: (p.stat().st_size, None) for name, p in paths.items()}
    for name, p in staged.items():
        os.replace(p, tdir / f"{name}.parquet")
        sizes[name] = (sizes.get(name, (None, None))[0], (tdir / f"{name}.parquet").stat().st_size)
    for name in set(paths) - set(new):
        paths[name].unlink()
    if records:
        os.replace(raw_stage, tdir / RAW_TABLES)
    else:
        raw_stage.unlink()
    return sizes


def study_transform(folder: Path) -> Callable[[dict], dict] | None:
    """The ``publish_tables`` of the study of a campaign-layout folder's ``campaign.json`` (None: tables kept)."""
    from renderlab import plugins

    manifest = Path(folder) / "campaign.json"
    if not manifest.is_file():
        raise UserError(f"{folder}: no campaign.json (for another folder kind call compact_folder with a transform)")
    study = json.loads(manifest.read_text(encoding="utf-8"))["plan"]["study"]
    if study not in plugins.studies:
        raise UserError(f"{folder}: study {study!r} is not registered")
    return plugins.studies.get(study).publish_tables


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m renderlab.campaign.compact",
                                 description="Compact the tables of published campaign folders in place (the "
                                             "folder's study's publish_tables; raw tables recorded).")
    ap.add_argument("folders", nargs="+", type=Path)
    ap.add_argument("--command", default="the campaign command of README.md, then renderlab publish",
                    help="how the full tables are regenerated (recorded in raw_tables.json)")
    args = ap.parse_args(argv)
    try:
        for folder in args.folders:
            sizes = compact_folder(folder, study_transform(folder), command=args.command)
            for name, (a, b) in sorted(sizes.items()):
                print(f"{folder}/tables/{name}.parquet: {a} -> {b if b is not None else 'removed'} bytes")
    except UserError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
