"""Publish the geometric coastline-EKF Monte Carlo (Straub & Christian Table 1, Figs. 5-9) into a folder.

    python -m renderlab.studies.coastline_ekf.publish --out results/coastline_ekf --runs 1000 --orbits all

Runs every orbit's Monte Carlo and writes the published layout of :mod:`.published` (``campaign.json``,
``runs.json``, ``tables/``: per orbit the per-time summary of all runs with the PCRB σ, the per-run NIS / NEES
totals, the first 25 runs' rows), then the report from those tables alone (``renderlab report OUT`` makes it
again): ``report/summary.csv`` (steady-state 3σ per axis for MC, filter and PCRB; χ² totals; timing),
``report/table1.md`` (Table 1's layout, ours beside the paper's), per orbit ``<case>_coastline_errors`` (Figs. 5-9
style) and ``<case>_coastline_consistency`` (PNG) and ``index.html``. ``--keep-runs`` also publishes every
run's rows (``tables/coastline_runs.parquet``, ≈5 MB per 200 runs of one orbit), from which the report then
recomputes the per-time summary.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from renderlab.errors import UserError
from renderlab.report.campaign_report import make_report
from renderlab.studies.coastline_ekf.geometric import PAPER_ORBITS, paper_orbit, run_batch, truth_geometry
from renderlab.studies.coastline_ekf.published import PAPER_TABLE1, orbit_tables, write_folder
from renderlab.studies.coastline_ekf.scoring import pcrb_ric_sigma, per_time_summary
from renderlab.studies.coastline_ekf.truth_options import with_truth


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m renderlab.studies.coastline_ekf.publish", description=__doc__.split("\n")[0])
    p.add_argument("--out", required=True, type=Path)
    p.add_argument("--runs", type=int, default=1000)
    p.add_argument("--orbits", default="all", help="comma list of i00_h1000,i45_h1000,i90_h1000,i45_h500,i90_h500")
    p.add_argument("--seed", type=int, default=2026)
    p.add_argument("--revolutions", type=float, default=1.0, help="duration in orbital periods")
    p.add_argument("--cadence-s", type=float, default=30.0)
    p.add_argument("--sigma-theta-mrad", type=float, default=0.5)
    p.add_argument("--points-per-image", type=int, default=16)
    p.add_argument("--chunk", type=int, default=250, help="runs per vectorised batch (memory)")
    p.add_argument("--keep-runs", action="store_true")
    p.add_argument("--truth-model", choices=["j2_rk4", "zonal_dop853"], default="j2_rk4",
                   help="truth propagator: the filter's class of model (default) or DOP853 with zonals J2..J6")
    p.add_argument("--zonal-degree", type=int, default=6, help="zonal_dop853: highest zonal degree")
    return p


def publish_orbit(case: str, args) -> dict:
    """Run one orbit's Monte Carlo → its published tables (:func:`.published.orbit_tables`)."""
    import pyarrow as pa

    o = paper_orbit(case, cadence_s=args.cadence_s, sigma_theta_rad=args.sigma_theta_mrad * 1e-3,
                    points_per_image=args.points_per_image)
    o = replace(o, duration_s=args.revolutions * o.period_s).validate()
    if getattr(args, "truth_model", "j2_rk4") != "j2_rk4":

        o = with_truth(o, truth_model=args.truth_model, zonal_degree=args.zonal_degree)
    t0 = time.perf_counter()
    geo = truth_geometry(o)
    t_geo = time.perf_counter() - t0
    seeds = np.random.SeedSequence([args.seed, list(PAPER_TABLE1).index(case)]).spawn(args.runs)
    t0 = time.perf_counter()
    parts = [run_batch(o, seeds[a:a + args.chunk], range(a, min(a + args.chunk, args.runs)), progress=True)["table"]
             for a in range(0, args.runs, args.chunk)]
    t_mc = time.perf_counter() - t0
    table = pa.concat_tables(parts)
    summary = per_time_summary(table, pcrb_ric_sigma(geo, o))
    return orbit_tables(case, o, geo, table, summary, {"geometry": t_geo, "monte_carlo": t_mc}, args.keep_runs)


def _plan(args, cases: list[str]) -> dict:
    """``campaign.json``'s plan: the command's options (the scenario of every orbit)."""
    opts = {k: v for k, v in sorted(vars(args).items()) if k not in ("out", "chunk")}
    name = "coastline_ekf_geometric" + ("" if args.out.name == "coastline_ekf" else f"_{args.out.name}")
    return {"name": name, "runs": args.runs, "seed": args.seed,
            "scenario": {"description": "geometric coastline-EKF Monte Carlo, Straub & Christian Table 1",
                         "world": {"kind": "earth"}, "trajectory": {"kind": "leo"},
                         "orbits": cases, "options": {k: v for k, v in opts.items() if k != "orbits"},
                         "perturbations": {"apriori_position_sigma_m": [500.0] * 3,
                                           "apriori_velocity_sigma_mps": [0.005] * 3}}}


def main(argv=None) -> int:
    args = _parser().parse_args(argv)

    cases = list(PAPER_ORBITS) if args.orbits == "all" else [c.strip() for c in args.orbits.split(",")]
    bad = [c for c in cases if c not in PAPER_ORBITS]
    if bad or args.runs < 1 or args.chunk < 1:
        raise UserError(f"unknown orbit {bad[0]!r}; choose from {', '.join(PAPER_ORBITS)}" if bad
                        else "--runs and --chunk must be >= 1")
    parts = [publish_orbit(c, args) for c in cases]
    write_folder(args.out, parts, _plan(args, cases))
    page = make_report(args.out, args.out / "report")
    print((args.out / "report" / "table1.md").read_text())
    print(f"published {args.out} (tables/, campaign.json, runs.json); report {page}")
    return 0


def run_module(entry, argv=None) -> int:
    """``python -m`` entry: a :class:`~renderlab.errors.UserError` is one line on stderr and exit code 2."""
    import sys


    try:
        return entry(argv)
    except UserError as err:
        print(f"renderlab: error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(run_module(main))
