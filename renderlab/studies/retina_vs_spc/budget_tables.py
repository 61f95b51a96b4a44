"""The error budget's raw tables (:mod:`.budget`): write them into a folder, read them back.

``tables/budget_measurements.parquet`` keeps the columns the budget is computed from (one row per landmark
attempted per frame, method and run, plus ``config``), ``tables/budget_configs.parquet`` one row per
configuration (``config``, ``source``, ``description``, ``runs``, ``overrides`` as JSON text),
``tables/budget_perturbations.parquet`` each run's drawn knowledge errors, ``budget.json`` the command.
"""

from __future__ import annotations

import json
from pathlib import Path

from renderlab.errors import UserError

TABLES = "tables"
MEASUREMENTS, CONFIGS, PERTURBATIONS = "budget_measurements", "budget_configs", "budget_perturbations"
MANIFEST = "budget.json"

#: the measurement columns kept
COLUMNS = ("config", "run", "frame", "item", "method", "peak", "truth_s", "truth_l", "err_s", "err_l", "has_result",
           "reason", "outlier", "truth_visible", "score", "search_px", "n_pixels", "gsd_ratio", "phase_deg",
           "shadow_fraction", "pred_shadow_fraction", "crlb_s", "crlb_l", "range_m")


def write_tables(out: Path, configs: list[dict], measurements, perturbations, manifest: dict) -> None:
    """Write the three tables and ``budget.json`` into ``out`` (staged: all or nothing)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from renderlab.campaign import store

    missing = [c for c in COLUMNS if c not in measurements.column_names]
    if missing:
        raise UserError(f"error budget: the measurement table lacks {missing[0]!r}")
    cfg = pa.table({"config": [c["config"] for c in configs], "source": [c["source"] for c in configs],
                    "description": [c["description"] for c in configs],
                    "runs": pa.array([int(c["runs"]) for c in configs], pa.int64()),
                    "overrides": [json.dumps(c["overrides"], sort_keys=True) for c in configs]})
    with store.staged_folder(Path(out), "the error budget") as stage:
        (stage / TABLES).mkdir()
        pq.write_table(measurements.select(list(COLUMNS)), stage / TABLES / f"{MEASUREMENTS}.parquet")
        pq.write_table(cfg, stage / TABLES / f"{CONFIGS}.parquet")
        pq.write_table(perturbations, stage / TABLES / f"{PERTURBATIONS}.parquet")
        (stage / MANIFEST).write_text(json.dumps(manifest, indent=2, sort_keys=True) + "\n", encoding="utf-8")


def read_tables(folder: Path) -> tuple:
    """(measurements, configs) pyarrow tables of a budget folder; UserError naming what is missing."""
    import pyarrow.parquet as pq

    d = Path(folder) / TABLES
    out = []
    for name in (MEASUREMENTS, CONFIGS):
        p = d / f"{name}.parquet"
        if not p.is_file():
            raise UserError(f"{folder}: no {TABLES}/{name}.parquet (not an error-budget folder; make one with "
                            "python -m renderlab.studies.retina_vs_spc.budget run)")
        try:
            out.append(pq.read_table(p))
        except Exception as err:  # pyarrow raises several types for a damaged file
            raise UserError(f"{p}: not a readable Parquet table ({type(err).__name__})") from None
    if "config" not in out[1].column_names or "all_off" not in out[1].column("config").to_pylist():
        raise UserError(f"{folder}: {CONFIGS}.parquet has no all_off configuration")
    return out[0], out[1]
