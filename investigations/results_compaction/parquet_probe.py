"""Probe (not run by tests): what re-encoding the published Parquet tables would save, measured on copies.

For every tracked ``results/**/*.parquet`` the table is read and written to a temporary folder with
(a) the current writer of ``renderlab publish`` (zstd level 9, pyarrow defaults) and (b) zstd 19 with
``BYTE_STREAM_SPLIT`` on floating-point columns and no dictionary for them; each copy is read back and compared
with the original table (the same schema and values, NaN equal to NaN). It also lists, per table, the columns
that take most bytes, and the columns equal (same values) to the same-named column of a companion folder's
table of the same name (the duplicates a compacted layout would store once).

Run from the repository root: ``.venv/bin/python investigations/results_compaction/parquet_probe.py``;
writes only under a temporary folder and prints a Markdown table.
"""

from __future__ import annotations

import argparse
import subprocess
import tempfile
from collections import defaultdict
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq


def _float_columns(t: pa.Table) -> list[str]:
    return [f.name for f in t.schema if pa.types.is_floating(f.type)]


def _same_array(x: pa.Array, y: pa.Array) -> bool:
    """Equal values, NaN equal to NaN (``Array.equals`` counts NaN as unequal); lists compared by offsets and
    flattened values."""
    if x.type != y.type or len(x) != len(y):
        return False
    if x.equals(y):
        return True
    if pa.types.is_list(x.type) or pa.types.is_large_list(x.type):
        return (x.offsets.equals(y.offsets) and x.is_null().equals(y.is_null())
                and _same_array(x.flatten(), y.flatten()))
    if pa.types.is_floating(x.type):
        a, b = x.to_numpy(zero_copy_only=False), y.to_numpy(zero_copy_only=False)
        return bool(np.array_equal(a, b, equal_nan=True))
    return False


def _same(t: pa.Table, u: pa.Table) -> bool:
    return t.schema.equals(u.schema) and all(
        _same_array(t.column(c).combine_chunks(), u.column(c).combine_chunks()) for c in t.column_names)


def _write(t: pa.Table, path: Path, mode: str) -> int:
    if mode == "publish":
        pq.write_table(t, path, compression="zstd", compression_level=9)
    else:
        floats = _float_columns(t)
        pq.write_table(t, path, compression="zstd", compression_level=19,
                       use_dictionary=[c for c in t.column_names if c not in floats],
                       column_encoding={c: "BYTE_STREAM_SPLIT" for c in floats} or None)
    back = pq.read_table(path)
    assert _same(back, t), path
    return path.stat().st_size


def _column_bytes(path: Path) -> dict[str, int]:
    md = pq.ParquetFile(path).metadata
    out: dict[str, int] = defaultdict(int)
    for g in range(md.num_row_groups):
        rg = md.row_group(g)
        for c in range(rg.num_columns):
            col = rg.column(c)
            out[col.path_in_schema.split(".")[0]] += col.total_compressed_size
    return dict(out)


def main() -> None:
    files = subprocess.run(["git", "ls-files", "results/*.parquet", "results/**/*.parquet"], capture_output=True,
                           text=True, check=True).stdout.split()
    tot = {"now": 0, "publish": 0, "split19": 0}
    rows = []
    tables = {}
    with tempfile.TemporaryDirectory(prefix="rl-parquet-probe-") as tmp:
        for k, f in enumerate(sorted(set(files))):
            p = Path(f)
            t = pq.read_table(p)
            tables[f] = t
            now = p.stat().st_size
            a = _write(t, Path(tmp) / f"{k}a.parquet", "publish")
            b = _write(t, Path(tmp) / f"{k}b.parquet", "split19")
            tot["now"] += now
            tot["publish"] += a
            tot["split19"] += b
            cb = _column_bytes(p)
            top = ", ".join(f"{c} {v / 1e6:.2f}" for c, v in sorted(cb.items(), key=lambda x: -x[1])[:3])
            rows.append((now, f, a, b, t.num_rows, t.num_columns, top))
    print("| table | rows × cols | now (MB) | zstd 9 (MB) | zstd 19 + split (MB) | largest columns (MB) |")
    print("|---|---|---|---|---|---|")
    for now, f, a, b, n, c, top in sorted(rows, reverse=True)[:25]:
        print(f"| {f} | {n} × {c} | {now / 1e6:.2f} | {a / 1e6:.2f} | {b / 1e6:.2f} | {top} |")
    print(f"\nall {len(rows)} tables: now {tot['now'] / 1e6:.1f} MB, zstd 9 {tot['publish'] / 1e6:.1f} MB, "
          f"zstd 19 + byte-stream-split {tot['split19'] / 1e6:.1f} MB")
    by_name = defaultdict(list)
    for f in tables:
        by_name[Path(f).name].append(f)
    shared = 0
    print("\n| table | companion with the same rows | columns with equal values | their bytes in the companion (MB) |")
    print("|---|---|---|---|")
    for _name, fs in sorted(by_name.items()):
        seen = set()
        for i, f in enumerate(fs):
            for g in fs[i + 1:]:
                t, u = tables[f], tables[g]
                if t.num_rows != u.num_rows or g in seen:
                    continue
                same = [c for c in t.column_names if c in u.column_names
                        and _same_array(t.column(c).combine_chunks(), u.column(c).combine_chunks())]
                if not same:
                    continue
                seen.add(g)
                extra = sum(_column_bytes(Path(g)).get(c, 0) for c in same)
                shared += extra
                print(f"| {f} | {g} | {len(same)} of {u.num_columns} ({', '.join(same[:6])}"
                      f"{', …' if len(same) > 6 else ''}) | {extra / 1e6:.2f} |")
    print(f"\ncolumns repeated across companions (same name, rows and values): {shared / 1e6:.1f} MB")


if __name__ == "__main__":
    argparse.ArgumentParser(description="Re-encode every tracked results/ Parquet table in a temporary folder and "
                            "print the sizes (Markdown); run from the repository root.").parse_args()
    main()
