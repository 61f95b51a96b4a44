"""``renderlab navigation-budget FOLDER``: the error budget's landmark errors flown through the descent filter.

A synthesis of two studies that stay independent of each other: the error budget's per-configuration landmark
error models (:mod:`renderlab.studies.retina_vs_spc.budget.navigation`) flown geometrically along the descent
study's truth (:mod:`renderlab.studies.descent_navigation.error_flights`); this command, a layer above the studies,
joins them: models → flights → ``FOLDER/tables/budget_navigation*.parquet`` → the budget's report
(:mod:`renderlab.studies.retina_vs_spc.budget.report`, which reads the tables alone). ``--only CONFIG ...`` flies
just those configurations (no floor) with the same runs and seed, so their rows replace those of the existing table
and equal what a full run gives; ``--methods METHOD ...`` likewise flies just those methods (of every configuration,
or of ``--only``'s), replacing only their rows.
"""

from __future__ import annotations

from pathlib import Path

from renderlab.errors import UserError
from renderlab.files.parquet_compact import write_compact_replacing
from renderlab.inputs import short


def add_parser(sub) -> None:
    n = sub.add_parser("navigation-budget", help="an error-budget folder's landmark errors flown through the descent "
                                                 "filter into FOLDER/tables, then the budget's report")
    n.add_argument("folder", metavar="FOLDER", help="error-budget folder (tables/budget_measurements.parquet, ...)")
    n.add_argument("--scenario", default="results/descent_navigation/scenario.toml",
                   help="the descent-navigation scenario (its folder holds the rendered campaign's tables)")
    n.add_argument("--runs", type=int, default=200, help="runs (the descent campaign's run indices 0..N-1)")
    n.add_argument("--seed", type=int, default=2027, help="seed of the injected landmark errors")
    n.add_argument("--workers", type=int, default=2, help="worker processes (1 to 4 per core)")
    n.add_argument("--mappings", nargs="+", default=None, help="mappings of the budget's statistics onto the "
                   "descent's altitudes (default: altitude ground pixel; see budget.navigation)")
    n.add_argument("--only", nargs="+", metavar="CONFIG", help="fly only these configurations and replace their "
                   "rows in FOLDER/tables/budget_navigation.parquet")
    n.add_argument("--methods", nargs="+", metavar="METHOD", help="fly only these landmark methods (same runs and "
                   "seed) and replace their rows in FOLDER/tables/budget_navigation.parquet")


def navigation_tables(folder, scenario_path, opts, workers: int = 2, only=None, methods=None) -> tuple:
    """(navigation table, rendered touchdown table) of a budget folder's error models
    (:func:`~renderlab.studies.retina_vs_spc.budget.navigation.error_models`, options ``opts``:
    :class:`~renderlab.studies.retina_vs_spc.budget.navigation.NavBudgetOptions`) flown along ``scenario_path``'s
    descent (:func:`~renderlab.studies.descent_navigation.error_flights.fly_models`); ``only``: just these
    configurations, ``methods``: just these methods, either: no floor."""
    from renderlab.studies.descent_navigation.error_flights import descent_geometry, fly_models, rendered_touchdown
    from renderlab.studies.retina_vs_spc.budget.navigation import MAPPINGS, NONE_CONFIG, NONE_METHOD, error_models
    from renderlab.studies.retina_vs_spc.budget.plan import BUDGET_TABLES

    if opts.runs < 2:
        raise UserError(f"--runs must be >= 2, got {opts.runs}")
    bad = sorted(set(opts.mappings) - set(MAPPINGS))
    if bad:
        raise UserError(f"--mappings: {short(bad[0])} is not one of {', '.join(MAPPINGS)}")
    meas, configs = BUDGET_TABLES.read(folder)
    geom = descent_geometry(scenario_path)
    models = [m for mp in opts.mappings
              for m in error_models(meas, configs, geom.camera.fx, geom.cfg.gsd_ratio_range, mp, opts.gross_px)]
    if only:
        unknown = sorted(set(only) - {m.config for m in models})
        if unknown:
            raise UserError(f"--only: the budget has no configuration {short(unknown[0])}")
        models = [m for m in models if m.config in only]
    if methods:
        unknown = sorted(set(methods) - {m.method for m in models})
        if unknown:
            raise UserError(f"--methods: the budget has no rows of method {short(unknown[0])}")
        models = [m for m in models if m.method in methods]
    table = fly_models(scenario_path, models, opts.runs, opts.seed, workers,
                       floor=None if only or methods else (NONE_CONFIG, NONE_METHOD))
    return table, rendered_touchdown(scenario_path)


def run_navigation(folder: Path, scenario_path: Path, runs: int, seed: int, workers: int, only=None,
                   mappings=None, methods=None) -> Path:
    """Fly the navigation budget (:func:`navigation_tables`) into ``folder/tables``, then the report (returned);
    ``only`` / ``methods``: those configurations' / methods' rows replaced in the existing table (same runs and
    seed; the other rows kept)."""
    import numpy as np
    import pyarrow as pa
    import pyarrow.compute as pc
    import pyarrow.parquet as pq

    from renderlab.campaign.oat_tables import TABLES
    from renderlab.studies.retina_vs_spc.budget.navigation import RENDERED, TABLE, NavBudgetOptions
    from renderlab.studies.retina_vs_spc.budget.report import write_report

    opts = NavBudgetOptions(runs=runs, seed=seed, **({"mappings": tuple(mappings)} if mappings else {}))
    nav, rendered = navigation_tables(folder, scenario_path, opts, workers, only, methods)
    if only or methods:
        old = pq.read_table(Path(folder) / TABLES / f"{TABLE}.parquet")
        if sorted(set(old.column("run").to_pylist())) != list(range(runs)):
            raise UserError(f"--only/--methods: the existing navigation table does not have runs 0..{runs - 1}")
        drop = pa.array(np.ones(old.num_rows, bool))
        for col, names in (("config", only), ("method", methods)):
            if names:
                drop = pc.and_(drop, pc.is_in(old.column(col), value_set=pa.array(list(names), pa.string())))
        keep = old.filter(pc.invert(drop))
        nav = pa.concat_tables([keep, nav.select(keep.column_names)])
    for name, table in ((TABLE, nav), (RENDERED, rendered)):
        write_compact_replacing(table, Path(folder) / TABLES / f"{name}.parquet")
    return write_report(folder)


def check_args(args) -> None:
    """``--workers`` capped as ``campaign``'s (each is a process), ``--runs`` and ``--seed`` in range, the folder a
    folder — before anything is read or started."""
    from renderlab.campaign.plan import MAX_RUNS
    from renderlab.commands.inputs import check_workers, existing_input

    check_workers(args.workers)
    if args.workers < 1:
        raise UserError(f"--workers must be at least 1, got {args.workers}")
    if not 2 <= args.runs <= MAX_RUNS:
        raise UserError(f"--runs must be in 2..{MAX_RUNS}, got {args.runs}")
    if not 0 <= args.seed < 2 ** 63:
        raise UserError(f"--seed must be in 0..2**63-1, got {args.seed}")
    existing_input(args.folder, "FOLDER")


def run(args) -> int:
    check_args(args)
    out = run_navigation(Path(args.folder), Path(args.scenario), args.runs, args.seed, args.workers, args.only,
                         args.mappings, args.methods)
    print(f"renderlab: wrote {Path(args.folder) / 'tables'} (budget_navigation, budget_navigation_rendered) and "
          f"the report {out}")
    return 0
