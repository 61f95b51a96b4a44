"""Regenerate every published report under a results tree with ``renderlab report FOLDER`` (each folder's README
command), one folder after another, and print the seconds each took.

Run from the folder that holds ``results/`` (the repository root, or a copy of it under /tmp), so each report names
its folder as ``results/...`` exactly as the README command does::

    .venv/bin/python investigations/results_compaction/regenerate.py [--root DIR] [--skip results/a,results/b]
                                                                     [--only results/c,results/d]

The folders: every ``report/index.html``'s folder, every ``crosscheck.md``'s folder and the error budget (the
result-folder kinds). Folders in ``--skip`` (other owners' new folders) are left alone; with ``--only`` just the
folders under those given (two invocations with complementary ``--only`` lists run side by side).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

RENDERLAB = Path(sys.executable).with_name("renderlab")


def folders(root: Path) -> list[str]:
    """The published folders under ``root/results`` (relative, POSIX), nested ones after their parents."""
    res = root / "results"
    found = {p.parent.parent for p in res.rglob("report/index.html")}
    found |= {p.parent for p in res.rglob("crosscheck.md")}
    found |= {p.parent.parent for p in res.rglob("report/budget_table.md")}
    return sorted(p.relative_to(root).as_posix() for p in found)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--root", default=".", help="folder that holds results/ (default: the current folder)")
    ap.add_argument("--skip", default="", help="comma-separated folders to leave alone")
    ap.add_argument("--only", default="", help="comma-separated folders: regenerate only these and those under them")
    args = ap.parse_args()
    root = Path(args.root).resolve()
    skip = {s.rstrip("/") for s in args.skip.split(",") if s}
    only = {s.rstrip("/") for s in args.only.split(",") if s}
    total = 0.0
    for f in folders(root):
        if any(f == s or f.startswith(s + "/") for s in skip):
            print(f"skip {f}", flush=True)
            continue
        if only and not any(f == s or f.startswith(s + "/") for s in only):
            continue
        t0 = time.perf_counter()
        proc = subprocess.run([str(RENDERLAB), "report", f], cwd=root, capture_output=True, text=True,
                              env={**os.environ, "PYTHONHASHSEED": "0"})
        dt = time.perf_counter() - t0
        total += dt
        print(f"{dt:7.1f} s  rc {proc.returncode}  {f}", flush=True)
        if proc.returncode:
            print(proc.stderr, file=sys.stderr)
            return 1
    print(f"{total:7.1f} s  all", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
