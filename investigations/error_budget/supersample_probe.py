"""Why Retina is not at the CRLB on exact models: its template sampling, measured (``docs/retina_vs_spc.md``).
``retina`` and ``retina_refined`` on the error budget's all-off truth with k × k template samples per pixel (k in
``SUPERSAMPLE`` of :mod:`renderlab.studies.retina_vs_spc.budget.report`), a-priori pose exact, into
``tables/budget_supersample.parquet`` of a budget folder, then the budget's report (``budget_supersample.csv``)::

    .venv/bin/python investigations/error_budget/supersample_probe.py results/error_budget
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pyarrow as pa

from renderlab.campaign.cache import cached_truthset
from renderlab.campaign.oat_tables import TABLES
from renderlab.campaign.perturb import draw_perturbation
from renderlab.errors import UserError
from renderlab.files.parquet_compact import write_compact_replacing
from renderlab.files.truthset import TruthSet
from renderlab.measurement.runner import MeasureOptions, measure_truthset
from renderlab.scenario import load_scenario, scenario_from_dict, truth_dict
from renderlab.sensor.model import SensorOptions
from renderlab.studies.retina_vs_spc.budget.plan import BUDGET_TABLES, budget_configs
from renderlab.studies.retina_vs_spc.budget.report import PROBE, SUPERSAMPLE, write_report
from renderlab.studies.retina_vs_spc.run import BelievedTruthSet
from renderlab.worlds.ev5.catalog import read_catalog


def probe_table(all_off: dict, base_dir: Path, workdir: Path, methods=("retina", "retina_refined")):
    """Rows of every method and k of :data:`SUPERSAMPLE` on the all-off truth set (module docstring)."""
    sc = scenario_from_dict(all_off, "error budget all_off")
    truth_sc = scenario_from_dict(truth_dict(sc.to_dict()), "error budget all_off truth")
    path, _ = cached_truthset(truth_sc, Path(base_dir), Path(workdir) / "truth_cache")
    ts = TruthSet.open(path)
    draw = draw_perturbation(sc.perturbations, np.random.SeedSequence(0))  # every σ is 0: the identity
    believed = BelievedTruthSet(ts, draw, SensorOptions(**sc.sensor.options_dict()), [0] * len(ts), noise=False)
    maplets = read_catalog(path)
    tables = []
    for k in SUPERSAMPLE:
        opts = MeasureOptions(sigma_pos_m=(0.0, 0.0, 0.0), sigma_att_rad=(0.0, 0.0, 0.0), supersample=k,
                              campaign="error_budget_probe")
        for m in methods:
            t = measure_truthset(believed, maplets, m, opts, np.random.default_rng(0))
            tables.append(t.append_column("supersample", pa.array([k] * t.num_rows, pa.int64())))
    keep = ("supersample", "method", "frame", "item", "err_s", "err_l", "has_result", "truth_visible", "gsd_ratio",
            "shadow_fraction")
    return pa.concat_tables(tables).select(list(keep))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description="Retina's template supersampling on the error budget's all-off truth")
    p.add_argument("folder", type=Path, help="an error-budget folder (its tables/ get budget_supersample.parquet)")
    p.add_argument("--scenario", type=Path, default=Path("results/retina_vs_spc/scenario.toml"))
    p.add_argument("--workdir", type=Path, default=Path("/tmp/renderlab_error_budget"), help="scratch (truth cache)")
    args = p.parse_args(argv)
    try:
        BUDGET_TABLES.read(args.folder)  # a budget folder first
        scenario, base_dir = load_scenario(args.scenario)
        all_off = next(c for c in budget_configs(scenario.to_dict()) if c["config"] == "all_off")
        table = probe_table(all_off["scenario"], base_dir, args.workdir)
        write_compact_replacing(table, args.folder / TABLES / f"{PROBE}.parquet")
        write_report(args.folder)
    except UserError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
