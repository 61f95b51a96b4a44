"""Closed-loop GN&C descent speed, from a ``descent_gnc`` campaign's own timing columns (no re-run).

Usage::

    .venv/bin/python benchmarks/bench_descent_gnc.py CAMPAIGN_OR_PUBLISHED_DIR

Reads ``gnc_runs`` (one row per run, method and mode; ``runs/*/gnc_runs.parquet`` of a campaign folder or
``tables/gnc_runs.parquet`` of a published one) and the runs' wall times (``runs/*/status.json`` or ``runs.json``).
Per flight the study records the wall seconds of the whole flight (``t_flight_ms``) and, summed over its images,
of the renders (``t_render_ms``), the landmark measurements (``t_measure_ms``) and the filter updates
(``t_filter_ms``); the rest of a flight is the truth integration, the guidance, the filter's propagation on the
accelerometer and the bookkeeping. A replay flight renders once for every method: its render time and its
flight time are split equally among the methods' rows, so the replay rows add up to one flight.

Printed: per mode and method the median seconds per flight and the median of each part with its ratio to that
median flight (medians: robust to the few flights that carry a worker's start-up — world and scene load, JIT
compilation — in the first run it executes); for all closed-loop flights together each part's share of their
summed time (start-up included); the Monte Carlo runs' wall times (median, p90, the sum in worker-minutes). The
campaign's own wall time and the machine's load are not in the tables: benchmarks/README.md states them.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from renderlab.campaign import store

PARTS = ("t_render_ms", "t_measure_ms", "t_filter_ms")


def read(folder: Path) -> tuple[dict, dict]:
    """(gnc_runs columns, {run: wall seconds}) of a campaign or published folder."""
    if (folder / "tables" / "gnc_runs.parquet").is_file():
        t = pq.read_table(folder / "tables" / "gnc_runs.parquet")
        status = store.published_statuses(folder)          # runs.json, the old bare list or the named file
    else:
        files = sorted((folder / "runs").glob("*/gnc_runs.parquet"))
        if not files:
            sys.exit(f"bench_descent_gnc: no gnc_runs table under {folder}")
        t = pa.concat_tables([pq.read_table(f) for f in files])
        status = [json.loads(p.read_text()) for p in sorted((folder / "runs").glob("*/status.json"))]
    cols = {n: np.asarray(t.column(n).to_pylist()) for n in ("run", "method", "mode", "t_flight_ms", *PARTS)}
    return cols, {int(s["run"]): float(s["seconds"]) for s in status if s.get("status") == "ok"}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("folder", type=Path)
    args = ap.parse_args(argv)
    c, wall = read(args.folder)
    print(f"{args.folder}: {len(set(c['run'].tolist()))} runs, {len(c['run'])} flights")
    print(f"{'mode':7s} {'method':13s} {'flight s':>9s} {'render':>14s} {'landmarks':>14s} {'filter':>14s} "
          f"{'rest':>14s}")
    for mode in ("closed", "replay"):
        for m in sorted(set(c["method"].tolist())):
            s = (c["mode"] == mode) & (c["method"] == m)
            if not s.any():
                continue
            flight = float(np.median(c["t_flight_ms"][s])) / 1e3
            parts = [float(np.median(c[p][s])) / 1e3 for p in PARTS]
            rest = float(np.median(c["t_flight_ms"][s] - sum(c[p][s] for p in PARTS))) / 1e3
            cells = " ".join(f"{v:6.2f} s {v / flight:4.0%}" for v in (*parts, rest))
            print(f"{mode:7s} {m:13s} {flight:8.2f}s {cells}")
    closed = c["mode"] == "closed"
    fl = c["t_flight_ms"][closed] / 1e3
    print(f"closed loop, all methods: median {np.median(fl):.2f} s per flight (p10 {np.percentile(fl, 10):.2f}, "
          f"p90 {np.percentile(fl, 90):.2f}); shares of the summed time: " + ", ".join(
              f"{p[2:-3]} {c[p][closed].sum() / c['t_flight_ms'][closed].sum():.0%}" for p in PARTS)
          + f", rest {1 - sum(c[p][closed].sum() for p in PARTS) / c['t_flight_ms'][closed].sum():.0%}")
    if wall:
        secs = sorted(wall.values())
        print(f"Monte Carlo run (every flight of a run, worker's wall time): median {statistics.median(secs):.1f} s, "
              f"p90 {np.percentile(secs, 90):.1f} s, max {secs[-1]:.1f} s, sum {sum(secs) / 60:.1f} worker-min over "
              f"{len(secs)} runs")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
