"""Error budget of the landmark methods against the registration Cramér–Rao bound (what each error source adds).

Every error source of the ``retina_vs_spc`` campaign is switched on alone, all others off, on the published
reduced EV5 scenario (``results/retina_vs_spc/scenario.toml``), plus "all off" and "all on"; every
method of :data:`METHODS` (Retina with the paper's 3×3 peak step, ``retina_refined`` with the ``gaussian_2d``
step, ``retina_ml`` with the maximum-likelihood shift of :mod:`estimators.retina.ml_shift`, SPC, the NCC baseline)
measures the same frames. The switches are scenario keys, nothing else:

==================== ============================================================================
source               "on" = the base scenario's value of
==================== ============================================================================
sensor_noise         ``retina_vs_spc.sensor_noise`` (off: the noise-free expected DN, rounded)
mapping_error        ``world.mapping_error_m`` (maplet height error; off: 0)
albedo_error         ``world.albedo_error_rms`` (maplet albedo error; off: 0)
photometric_law      ``world.law`` / ``law_params`` (Hapke truth; off: McEwen truth, the onboard form,
                     so the onboard L(α) fit is exact)
apriori_pose         ``perturbations.apriori_position_sigma_m``, ``apriori_attitude_sigma_deg``
camera_knowledge     ``perturbations.focal_length_sigma_frac``, ``principal_point_sigma_px``,
                     ``distortion_sigma``
sun_knowledge        ``perturbations.sun_direction_sigma_deg``
maplet_spacing       ``perturbations.maplet_spacing_sigma_frac``
==================== ============================================================================

The peak step is not a scenario switch but a method: ``retina`` (3×3 step) beside ``retina_refined`` in every
configuration (:mod:`.budget_stats` reports the difference). The shadow approximation is measured the same way,
at all off: configuration ``no_shadows`` is every source off with no cast shadows in the truth
(``render.shadows = false``) nor in the methods' predictions (:mod:`.budget_shadows` says why both); every
other configuration has ray-traced cast shadows in the truth and each method's own shadowing in its template.
``run --only CONFIG ...`` runs just those configurations into an existing folder's tables (the rest kept);
``run --methods METHOD ...`` just those methods of every configuration (same seeds and run indices, so their rows
are paired with the others'; the merge checks the truth columns and knowledge draws agree).

The truth render depends only on the world keys (law, mapping and albedo error: five truth sets, the
others share the "all off" one through the truth cache). Configurations with no random draw (sensor
noise off, no perturbation on) give identical runs, so they run once. Every configuration uses the same
campaign seed and run indices, so runs ``i`` of two configurations share their noise and draws (common
random numbers). Written, into ``--out``: ``tables/budget_measurements.parquet`` (every row of every run,
column ``config``), ``tables/budget_configs.parquet`` (configuration, source, runs, overrides as JSON),
``tables/budget_perturbations.parquet``, ``budget.json`` (command, seed, runs) and the report
(:mod:`.budget_report`), which ``report`` makes again from the tables alone::

    python -m renderlab.studies.retina_vs_spc.budget run --out results/error_budget --runs 10 --workers 2
    python -m renderlab.studies.retina_vs_spc.budget probe results/error_budget   # template sampling (.budget_probe)
    python -m renderlab.studies.retina_vs_spc.budget report results/error_budget

The navigation budget (each configuration's landmark errors flown through the descent filter,
:mod:`.budget_navigation`) joins this study to ``descent_navigation``, so it is a command above both:
``renderlab navigation-budget results/error_budget --runs 200`` (:mod:`renderlab.commands.navigation_budget`).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from renderlab import plugins
from renderlab.campaign.plan import run_seed_sequence
from renderlab.errors import UserError
from renderlab.scenario import load_scenario, scenario_from_dict, truth_dict
from renderlab.studies.retina_vs_spc import budget_shadows as SH
from renderlab.studies.retina_vs_spc.budget_plan import (  # noqa: F401
    METHODS,
    OFF,
    SOURCES,
    _get,
    _set,
    budget_configs,
    stochastic,
    with_section,
)
from renderlab.studies.retina_vs_spc.budget_probe import PROBE, probe_table
from renderlab.studies.retina_vs_spc.budget_report import write_report
from renderlab.studies.retina_vs_spc.budget_tables import TABLES, merge_tables, read_tables, write_tables
from renderlab.studies.retina_vs_spc.run import run, section


def _one_run(task):
    """Worker: one run of one configuration → (config, run, measurements, perturbations, seconds)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    name, sc_dict, base_dir, index, seed, workdir = task
    t0 = time.perf_counter()
    done = _done_paths(task)
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


def _done_paths(task) -> tuple[Path, Path]:
    """Where a finished run of ``task`` is kept in the scratch folder (keyed by scenario content, seed, run)."""
    import hashlib

    name, sc_dict, _, index, seed, workdir = task
    key = hashlib.sha256(json.dumps([sc_dict, seed, index], sort_keys=True).encode()).hexdigest()[:16]
    d = Path(workdir) / "budget_runs"
    return d / f"{name}_{index:03d}_{key}_m.parquet", d / f"{name}_{index:03d}_{key}_p.parquet"


def _tasks(configs, base_dir, runs, seed, workdir) -> tuple[list, list]:
    """(first tasks: one per distinct truth, rest): no two workers render the same truth at once."""
    first, rest, seen = [], [], set()
    for c in configs:
        n = runs if stochastic(c["scenario"]) else 1
        c["runs"] = n
        key = json.dumps(truth_dict(c["scenario"]), sort_keys=True)
        for i in range(n):
            task = (c["config"], c["scenario"], str(base_dir), i, seed, str(workdir))
            (rest if key in seen else first).append(task)
            seen.add(key)
    return first, sorted(rest, key=lambda task: task[3])  # run-major: every configuration advances together


def run_budget(scenario_path: Path, out: Path, runs: int, workers: int, workdir: Path, command: str,
               only: list[str] | None = None, methods: list[str] | None = None) -> None:
    """Run every configuration (progress on stderr), write the tables and ``budget.json``, then the report.
    ``only``: run just these configurations and merge them into ``out``'s existing tables; ``methods``: run just
    these methods (same seeds and run indices) and merge their rows, the other methods' rows kept
    (:func:`.budget_tables.merge_tables`, which refuses rows whose truth or draws differ from the table's)."""
    import concurrent.futures as cf

    import pyarrow as pa


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

        read_tables(out)  # an existing budget folder to merge into, before anything runs
    first, rest = _tasks(configs, base_dir, runs, seed, workdir)
    total, done, t0 = len(first) + len(rest), 0, time.perf_counter()
    meas, pert = [], []
    with cf.ProcessPoolExecutor(max_workers=max(1, workers)) as pool:
        for batch in (first, rest):
            for name, i, m, p, dt in pool.map(_one_run, batch):
                done += 1
                meas.append(m)
                pert.append(p)
                print(f"[{done}/{total}] {name} run {i}: {m.num_rows} rows, {dt:.1f} s "
                      f"(elapsed {time.perf_counter() - t0:.0f} s)", file=sys.stderr, flush=True)
    manifest = {"command": command, "scenario": scenario_path.name, "seed": seed, "runs": runs,
                "wall_s": round(time.perf_counter() - t0, 1), "workers": workers}
    m, p = pa.concat_tables(meas, promote_options="default"), pa.concat_tables(pert, promote_options="default")
    if only or methods:

        merge_tables(out, configs, m, p, manifest, methods)
    else:
        write_tables(out, configs, m, p, manifest)

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
    q = sub.add_parser("probe", help="Retina's template supersampling on the all-off truth (.budget_probe) into "
                                     "FOLDER/tables, then the report")
    q.add_argument("folder", type=Path)
    q.add_argument("--scenario", type=Path, default=Path("results/retina_vs_spc/scenario.toml"))
    q.add_argument("--workdir", type=Path, default=Path("/tmp/renderlab_error_budget"))
    return p


def run_probe(folder: Path, scenario_path: Path, workdir: Path) -> None:
    """Measure the probe's rows (:func:`.budget_probe.probe_table`) into ``folder/tables``, then the report."""
    import pyarrow.parquet as pq


    read_tables(folder)  # a budget folder first
    scenario, base_dir = load_scenario(scenario_path)
    all_off = next(c for c in budget_configs(scenario.to_dict()) if c["config"] == "all_off")
    table = probe_table(all_off["scenario"], base_dir, workdir)
    out = Path(folder) / TABLES / f"{PROBE}.parquet"
    tmp = out.with_name(f".{out.name}.tmp")
    pq.write_table(table, tmp)
    tmp.replace(out)
    write_report(folder)


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        if args.command == "run":
            from renderlab.campaign.executors import check_workers

            if args.workers < 1:
                raise UserError(f"--workers must be at least 1, got {args.workers}")
            check_workers(args.workers)  # each is a process: capped like campaign's
            cmd = "python -m renderlab.studies.retina_vs_spc.budget " + " ".join(sys.argv[1:] if argv is None else argv)
            run_budget(args.scenario, args.out, args.runs, args.workers, args.workdir, cmd, args.only,
                       args.methods)
        elif args.command == "probe":
            run_probe(args.folder, args.scenario, args.workdir)
        else:

            out = write_report(args.folder)
            print(f"renderlab: wrote {out} (budget_summary.csv, budget_terms.csv, budget_table.md, "
                  "error_budget.png/.svg)")
    except UserError as err:
        print(f"renderlab: error: {err}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
