"""Rewrite the ``runs.json`` of published campaign folders in the named format (``renderlab.runs/1``: the statuses
under the digest of the folder's ``campaign.json`` plan, :func:`renderlab.campaign.store.write_statuses`), so that
two campaigns whose runs all ended alike no longer hold byte-identical run-status files. The statuses themselves
are kept as they are; a folder already in the named format is left alone.

    .venv/bin/python investigations/results_compaction/name_run_statuses.py results/FOLDER [...]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from renderlab.campaign import store


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("folders", nargs="+", type=Path)
    args = ap.parse_args(argv)
    for folder in args.folders:
        if isinstance(json.loads((folder / store.STATUSES).read_text()), dict):
            print(f"{folder}: already named")
            continue
        statuses = store.published_statuses(folder)          # validated, each run once
        store.write_statuses(folder, store.read_manifest(folder), statuses)
        print(f"{folder}/{store.STATUSES}: {len(statuses)} runs under plan digest "
              f"{json.loads((folder / store.STATUSES).read_text())['plan_digest']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
