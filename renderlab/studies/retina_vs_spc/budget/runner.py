"""The error budget's commands (``python -m renderlab.studies.retina_vs_spc.budget run|report``): each
configuration of :mod:`.plan` run through the study's own ``run`` by the generic one-at-a-time core
(:func:`renderlab.campaign.oat_budget.run_configs`), the tables written or merged (:mod:`renderlab.campaign.oat_tables`),
then the report (:mod:`.report`). The package docstring says what the budget measures."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

from renderlab import plugins
from renderlab.campaign.oat_budget import done_paths, run_configs
from renderlab.campaign.plan import run_seed_sequence
from renderlab.errors import UserError, run_main
from renderlab.scenario import load_scenario, scenario_from_dict
from renderlab.studies.retina_vs_spc.budget import shadows as SH
from renderlab.studies.retina_vs_spc.budget.plan import BUDGET_TABLES, METHODS, budget_configs, stochastic
from renderlab.studies.retina_vs_spc.budget.report import write_report
from renderlab.studies.retina_vs_spc.run import run, section


def _one_run(task):
    """Worker: one run of one configuration → (config, run, measurements, perturbations, seconds)."""
    name, sc_dict, base_dir, index, seed, workdir = task
    t0 = time.perf_counter()
    done = done_paths(task)
    if all(p.is_file() for p in done):  # finished by an earlier, interrupted call (same scenario, seed, run)
        return name, index, pq.read_table(done[0]), pq.read_table(done[1]), 0.0
    scenario = scenario_from_dict(sc_dict, f"error budget configuration {name}")
    methods = SH.factories(section(scenario).methods) if name == SH.CONFIG else None
    out = run(scenario, Path(base_dir), index, run_seed_sequence(seed, index), Path(workdir), methods=methods)
    tabs = []
    for key, path in zip(("measurements", "perturbations"), done):
        t = out[key]
        tabs.append(t.append_column("config", pa.array([name] * t.num_rows, pa.string())))
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.name}.tmp")
        pq.write_table(tabs[-1], tmp)
        tmp.replace(path)
    return name, index, tabs[0], tabs[1], time.perf_counter() - t0


def run_budget(scenario_path: Path, out: Path, runs: int, workers: int, workdir: Path, command: str,
               only: list[str] | None = None, methods: list[str] | None = None) -> None:
    """Run every configuration, write the tables and ``budget.json``, then the report; ``only`` / ``methods``: just
    these configurations / methods, merged into ``out``'s tables (:func:`renderlab.campaign.oat_tables.merge_tables`)."""
    if runs < 2:
        raise UserError(f"--runs must be >= 2 (noise needs repeated runs), got {runs}")
    scenario, base_dir = load_scenario(scenario_path)
    base = scenario.to_dict()
    seed = int(base.get("campaign", {}).get("seed", 0))
    configs = budget_configs(base, _known_methods(methods) if methods else METHODS)
    if only:
        unknown = sorted(set(only) - {c["config"] for c in configs})
        if unknown:
            raise UserError(f"--only: no configuration {unknown[0]!r} (known: "
                            f"{', '.join(c['config'] for c in configs)})")
        configs = [c for c in configs if c["config"] in only]
    if only or methods:
        BUDGET_TABLES.read(out)  # an existing budget folder to merge into, before anything runs
    m, p, wall = run_configs(configs, _one_run, base_dir=base_dir, runs=runs, seed=seed, workers=workers,
                             workdir=workdir, stochastic=stochastic)
    manifest = {"command": command, "scenario": scenario_path.name, "seed": seed, "runs": runs,
                "wall_s": round(wall, 1), "workers": workers}
    if only or methods:
        BUDGET_TABLES.merge(out, configs, m, p, manifest, methods)
    else:
        BUDGET_TABLES.write(out, configs, m, p, manifest)
    write_report(out)


def _known_methods(methods: list[str]) -> list[str]:
    """``methods`` if each is a registered landmark method, listed once; else UserError."""
    if len(set(methods)) != len(methods):
        raise UserError(f"--methods: a method is named twice ({' '.join(methods)})")
    for name in methods:
        plugins.landmark_methods.get(name, where="--methods: ")
    return list(methods)


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m renderlab.studies.retina_vs_spc.budget",
                                description="Error budget of the landmark methods against the registration CRLB")
    sub = p.add_subparsers(dest="command", required=True)
    r = sub.add_parser("run", help="run every configuration and write tables + report into --out")
    r.add_argument("--scenario", type=Path, default=Path("results/retina_vs_spc/scenario.toml"),
                   help="base scenario (all sources on)")
    r.add_argument("--out", type=Path, required=True, help="output folder (tables/, budget.json, report files)")
    r.add_argument("--runs", type=int, default=20, help="runs per configuration that has random draws")
    r.add_argument("--workers", type=int, default=2, help="worker processes")
    r.add_argument("--workdir", type=Path, default=Path("/tmp/renderlab_error_budget"),
                   help="scratch folder (truth cache)")
    r.add_argument("--only", nargs="+", metavar="CONFIG",
                   help="run only these configurations and merge them into --out's existing tables")
    r.add_argument("--methods", nargs="+", metavar="METHOD",
                   help="run only these landmark methods (same seeds and runs) and merge their rows into --out's "
                        "existing tables, the other methods' rows kept (their truth and draws must agree)")
    g = sub.add_parser("report", help="make the table and figure again from FOLDER/tables alone")
    g.add_argument("folder", type=Path)
    return p


def _main(argv: list[str] | None) -> int:
    args = _parser().parse_args(argv)
    if args.command == "report":
        print(f"renderlab: wrote {write_report(args.folder)} (budget_summary.csv, budget_terms.csv, budget_table.md, "
              "error_budget.png)")
        return 0
    from renderlab.campaign.executors import check_workers

    if args.workers < 1:
        raise UserError(f"--workers must be at least 1, got {args.workers}")
    check_workers(args.workers)  # each is a process: capped like campaign's
    cmd = "python -m renderlab.studies.retina_vs_spc.budget " + " ".join(sys.argv[1:] if argv is None else argv)
    run_budget(args.scenario, args.out, args.runs, args.workers, args.workdir, cmd, args.only, args.methods)
    return 0


def main(argv: list[str] | None = None) -> int:
    """The command line (:func:`renderlab.errors.run_main`: a UserError is one line and exit code 2)."""
    return run_main(_main, argv)


if __name__ == "__main__":
    sys.exit(main())
