"""``renderlab campaign SCENARIO --runs N --out DIR [--workers N | --scheduler ADDRESS] [--resume] [--set ...]``"""

from __future__ import annotations

from pathlib import Path

from renderlab.commands import cost
from renderlab.commands.cost import load_checked
from renderlab.inputs import short


def _int(lo: int):
    import argparse

    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer >= {lo}, got {short(text)}") from None
        if v < lo:
            raise argparse.ArgumentTypeError(f"expected an integer >= {lo}, got {short(text)}")
        return v
    return parse


#: the longest ``--connect-timeout`` (an hour: a scheduler that takes longer to answer is not there)
MAX_CONNECT_TIMEOUT_S = 3600.0


def _positive_float(text: str) -> float:
    import argparse
    import math

    try:
        v = float(text)
    except ValueError:
        v = math.nan
    if not (0 < v <= MAX_CONNECT_TIMEOUT_S):
        raise argparse.ArgumentTypeError(f"expected a number of seconds in (0, {MAX_CONNECT_TIMEOUT_S:g}], got "
                                         f"{short(text)}")
    return v


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("campaign", help="run a seeded, resumable Monte Carlo campaign of a scenario's study")
    p.add_argument("scenario", metavar="SCENARIO", help="scenario TOML file ([perturbations], [campaign] sections)")
    p.add_argument("--runs", type=_int(1), required=True, metavar="N", help="number of Monte Carlo runs")
    p.add_argument("--out", required=True, metavar="DIR", help="campaign folder (created; see --resume)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--workers", type=_int(0), metavar="N",
                       help="local Dask workers (default: one per core); 0 runs in this process (debugging)")
    where.add_argument("--scheduler", metavar="ADDRESS",
                       help="use an existing Dask cluster (tcp://host:8786, or tls://host:8786 with --tls-*); Dask's "
                            "protocol can run code, so name only a scheduler you trust")
    p.add_argument("--connect-timeout", type=_positive_float, default=10.0, metavar="S",
                   help="seconds to wait for --scheduler to accept and to answer (default 10)")
    p.add_argument("--tls-ca-file", metavar="FILE", help="CA certificate that signed the tls:// scheduler's certificate")
    p.add_argument("--tls-cert", metavar="FILE", help="this client's TLS certificate (with --tls-key)")
    p.add_argument("--tls-key", metavar="FILE", help="this client's TLS private key (with --tls-cert)")
    p.add_argument("--resume", action="store_true", help="continue DIR: skip finished runs, redo the rest")
    p.add_argument("--seed", type=_int(0), metavar="S", help="override campaign.seed")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", dest="overrides",
                   help="override a scenario key (TOML value); repeatable")
    p.add_argument("--plugin", action="append", default=[], metavar="[NAME=]MODULE:ATTR",
                   help="register your own landmark method (or Study) under NAME (default: its 'name') for this "
                        "campaign, e.g. --plugin mypkg.method:MyMethod; repeatable. Scenario files name only "
                        "registered names, never modules")
    p.add_argument("--timings", choices=["inline", "separate"], default="inline",
                   help="wall-clock timing columns (t_ms, ...): in the result tables (default), or 'separate': "
                        "zeroed there and kept in runs/NNNNNN/timings.parquet, so the same seed gives "
                        "byte-identical result tables")
    p.add_argument("--allow-large", action="store_true",
                   help="run past the cost limits (pixels × spp × frames × runs, memory, disk; see renderlab.commands.cost)")
    p.add_argument("--dry-run", action="store_true",
                   help="check the request and print what would be run (runs, frames, rays, disk), creating nothing")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def run(args) -> int:
    from renderlab.campaign.executors import check_scheduler_options, check_workers, make_executor
    from renderlab.campaign.plan import make_plan
    from renderlab.campaign.runner import run_campaign
    from renderlab.commands.inputs import check_scenario_inputs
    from renderlab.plugins import register_cli_plugins

    check_workers(args.workers)
    security = check_scheduler_options(args.scheduler, args.tls_ca_file, args.tls_cert, args.tls_key)
    scenario, base = load_checked(args.scenario, args.overrides)
    check_scenario_inputs(scenario, base)
    from renderlab.commands.references import check_plugin

    for text in args.plugin:
        check_plugin(text)  # imported and checked against the protocols before it is registered or called
    refs = register_cli_plugins(args.plugin)
    plan = make_plan(scenario, base, args.runs, seed=args.seed, plugins=refs)
    if args.dry_run:
        from renderlab.commands.dryrun import campaign_dry_run

        return campaign_dry_run(scenario, plan, args)
    cost.check_scenario(scenario, runs=args.runs, out=args.out, allow_large=args.allow_large,
                        what=f"campaign of {args.runs} runs of {Path(args.scenario).name}")
    if args.scheduler:  # before anything is created: a scheduler that does not answer is refused in time
        from renderlab.campaign.executors import probe_scheduler

        probe_scheduler(args.scheduler, args.connect_timeout, security)
    workers = None if args.workers is None else min(args.workers, args.runs)
    executor = make_executor(workers, args.scheduler, args.connect_timeout, security=security)
    res = run_campaign(plan, Path(args.out), executor=executor, resume=args.resume, progress=not args.quiet,
                       timings=args.timings)
    msg = (f"renderlab: campaign {res.path}: {res.runs - len(res.failed)} of {res.runs} runs finished "
           f"({res.executed} executed now, {res.skipped} already done)")
    if res.failed:
        msg += f"; {len(res.failed)} failed (first: run {res.failed[0]['run']}: {res.failed[0]['error']})"
    print(msg)
    return 0
