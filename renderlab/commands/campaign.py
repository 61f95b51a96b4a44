"""``renderlab campaign SCENARIO --runs N --out DIR [--workers N | --scheduler ADDRESS] [--resume] [--set ...]``"""

from __future__ import annotations

from pathlib import Path


def _int(lo: int):
    import argparse

    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer >= {lo}, got {text!r}") from None
        if v < lo:
            raise argparse.ArgumentTypeError(f"expected an integer >= {lo}, got {text!r}")
        return v
    return parse


def _positive_float(text: str) -> float:
    import argparse
    import math

    try:
        v = float(text)
    except ValueError:
        v = math.nan
    if not (v > 0 and math.isfinite(v)):
        raise argparse.ArgumentTypeError(f"expected a positive number of seconds, got {text!r}")
    return v


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("campaign", help="run a seeded, resumable Monte Carlo campaign of a scenario's study")
    p.add_argument("scenario", metavar="SCENARIO", help="scenario TOML file ([perturbations], [campaign] sections)")
    p.add_argument("--runs", type=_int(1), required=True, metavar="N", help="number of Monte Carlo runs")
    p.add_argument("--out", required=True, metavar="DIR", help="campaign folder (created; see --resume)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--workers", type=_int(0), metavar="N",
                       help="local Dask workers (default: one per core); 0 runs in this process (debugging)")
    where.add_argument("--scheduler", metavar="ADDRESS", help="use an existing Dask cluster (tcp://host:8786)")
    p.add_argument("--connect-timeout", type=_positive_float, default=10.0, metavar="S",
                   help="seconds to wait for --scheduler (default 10)")
    p.add_argument("--resume", action="store_true", help="continue DIR: skip finished runs, redo the rest")
    p.add_argument("--seed", type=_int(0), metavar="S", help="override campaign.seed")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", dest="overrides",
                   help="override a scenario key (TOML value); repeatable")
    p.add_argument("--plugin", action="append", default=[], metavar="[NAME=]MODULE:ATTR",
                   help="register your own landmark method (or Study) under NAME (default: its 'name') for this "
                        "campaign, e.g. --plugin mypkg.method:MyMethod; repeatable. Scenario files name only "
                        "registered names, never modules")
    p.add_argument("--dry-run", action="store_true",
                   help="check the request and print what would be run (runs, frames, rays, disk), creating nothing")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def run(args) -> int:
    from renderlab.campaign.executors import make_executor
    from renderlab.campaign.plan import make_plan
    from renderlab.campaign.runner import run_campaign
    from renderlab.scenario import load_scenario

    from renderlab.plugins import register_cli_plugins

    refs = register_cli_plugins(args.plugin)
    scenario, base = load_scenario(args.scenario, args.overrides)
    plan = make_plan(scenario, base, args.runs, seed=args.seed, plugins=refs)
    if args.dry_run:
        from renderlab.commands.dryrun import campaign_dry_run

        return campaign_dry_run(scenario, plan, args)
    executor = make_executor(args.workers, args.scheduler, args.connect_timeout)
    res = run_campaign(plan, Path(args.out), executor=executor, resume=args.resume, progress=not args.quiet)
    msg = (f"renderlab: campaign {res.path}: {res.runs - len(res.failed)} of {res.runs} runs finished "
           f"({res.executed} executed now, {res.skipped} already done)")
    if res.failed:
        msg += f"; {len(res.failed)} failed (first: run {res.failed[0]['run']}: {res.failed[0]['error']})"
    print(msg)
    return 0
