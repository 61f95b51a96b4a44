"""The raw tables of a one-at-a-time error budget (:mod:`renderlab.campaign.oat_budget`): write them into a
folder, read them back, merge a partial rerun into them.

``tables/budget_measurements.parquet`` keeps the columns a budget is computed from (one row per item attempted per
frame, method and run, plus ``config``), ``tables/budget_configs.parquet`` one row per configuration (``config``,
``source``, ``description``, ``runs``, ``overrides`` as JSON text), ``tables/budget_perturbations.parquet`` each
run's drawn knowledge errors, ``budget.json`` the command. Which measurement columns are kept, and which of them a
rerun of some methods must reproduce, is the study's :class:`OatTables`.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from renderlab.campaign import store
from renderlab.errors import UserError
from renderlab.files.parquet_compact import write_compact, write_compact_replacing

TABLES = "tables"
MEASUREMENTS, CONFIGS, PERTURBATIONS = "budget_measurements", "budget_configs", "budget_perturbations"
MANIFEST = "budget.json"
#: largest |new − old| of a paired column (px, m, deg, ...; the CRLB relative) still counted as the same truth
PAIR_TOL, PAIR_TOL_CRLB_REL = 1e-9, 1e-9


@dataclass(frozen=True)
class OatTables:
    """A study's budget tables: the measurement ``columns`` kept, the truth ``paired`` columns a ``--methods``
    rerun must reproduce on every (config, run, frame, item) it shares with the table, and the ``make`` command
    named when a folder is not a budget folder."""

    columns: tuple[str, ...]
    paired: tuple[str, ...]
    make: str

    def write(self, out: Path, configs: list[dict], measurements, perturbations, manifest: dict) -> None:
        write_tables(out, configs, measurements, perturbations, manifest, self.columns)

    def read(self, folder: Path) -> tuple:
        return read_tables(folder, self.make)

    def merge(self, out: Path, configs: list[dict], meas, pert, manifest: dict, methods=None) -> None:
        merge_tables(out, configs, meas, pert, manifest, methods, self.columns, self.paired)


def _config_table(configs: list[dict]):
    import pyarrow as pa

    return pa.table({"config": pa.array([c["config"] for c in configs], pa.string()),
                     "source": [c["source"] for c in configs], "description": [c["description"] for c in configs],
                     "runs": pa.array([int(c["runs"]) for c in configs], pa.int64()),
                     "overrides": [json.dumps(c["overrides"], sort_keys=True) for c in configs]})


def write_tables(out: Path, configs: list[dict], measurements, perturbations, manifest: dict,
                 columns: tuple[str, ...]) -> None:
    """Write the three tables (measurements: ``columns`` only) and ``budget.json`` into ``out`` (staged: all or
    nothing)."""

    missing = [c for c in columns if c not in measurements.column_names]
    if missing:
        raise UserError(f"error budget: the measurement table lacks {missing[0]!r}")
    cfg = _config_table(configs)
    with store.staged_folder(Path(out), "the error budget") as stage:
        (stage / TABLES).mkdir()
        write_compact(measurements.select(list(columns)), stage / TABLES / f"{MEASUREMENTS}.parquet")
        write_compact(cfg, stage / TABLES / f"{CONFIGS}.parquet")
        write_compact(perturbations, stage / TABLES / f"{PERTURBATIONS}.parquet")
        (stage / MANIFEST).write_text(json.dumps(manifest, indent=2, sort_keys=True) + "\n", encoding="utf-8")


def read_tables(folder: Path, make: str) -> tuple:
    """(measurements, configs) pyarrow tables of a budget folder; UserError naming what is missing (and ``make``,
    the command that makes such a folder)."""
    import pyarrow.parquet as pq

    d = Path(folder) / TABLES
    out = []
    for name in (MEASUREMENTS, CONFIGS):
        p = d / f"{name}.parquet"
        if not p.is_file():
            raise UserError(f"{folder}: no {TABLES}/{name}.parquet (not an error-budget folder; make one with "
                            f"{make})")
        try:
            out.append(pq.read_table(p))
        except Exception as err:  # pyarrow raises several types for a damaged file
            raise UserError(f"{p}: not a readable Parquet table ({type(err).__name__})") from None
    if "config" not in out[1].column_names or "all_off" not in out[1].column("config").to_pylist():
        raise UserError(f"{folder}: {CONFIGS}.parquet has no all_off configuration")
    return out[0], out[1]


def paired_check(old, new, paired: tuple[str, ...]) -> dict:
    """{column: max |new − old|} (``crlb_*``: relative) over the keys (config, run, frame, item) the new rows share
    with ``old``'s rows of one other method, and ``perturbations``: whether their knowledge draws agree; UserError
    when a key is missing or a value differs beyond :data:`PAIR_TOL` (the new rows would not be paired)."""
    import numpy as np

    key = ("config", "run", "frame", "item")
    ref_method = sorted(set(old.column("method").to_pylist()) - set(new.column("method").to_pylist()))
    if not ref_method:
        raise UserError("--methods: the table has no other method to pair the new rows with")
    o = old.filter(_eq(old, "method", ref_method[0]))
    index = {k: j for j, k in enumerate(zip(*[o.column(c).to_pylist() for c in key]))}
    out = {}
    for m in sorted(set(new.column("method").to_pylist())):
        n = new.filter(_eq(new, "method", m))
        keys = list(zip(*[n.column(c).to_pylist() for c in key]))
        missing = [k for k in keys if k not in index]
        if missing or len(keys) != o.num_rows:
            raise UserError(f"--methods: {m}'s rows do not cover the same landmark-frames as {ref_method[0]}'s "
                            f"({len(missing)} new keys, {len(keys)} vs {o.num_rows} rows)")
        j = np.array([index[k] for k in keys])
        for c in paired:
            a = np.asarray(o.column(c).to_numpy(zero_copy_only=False), float)[j]
            b = np.asarray(n.column(c).to_numpy(zero_copy_only=False), float)
            if not np.array_equal(np.isfinite(a), np.isfinite(b)):
                raise UserError(f"--methods: column {c} of {m}'s rows is NaN where {ref_method[0]}'s is not (or "
                                "the reverse): not the table's truth")
            f = np.isfinite(a)
            d = np.abs(b[f] - a[f]) / (np.abs(a[f]) if c.startswith("crlb") else 1.0)
            out[c] = max(out.get(c, 0.0), float(d.max()) if d.size else 0.0)
            tol = PAIR_TOL_CRLB_REL if c.startswith("crlb") else PAIR_TOL
            if out[c] > tol:
                raise UserError(f"--methods: {m}'s {c} differs from the table's ({ref_method[0]}) by {out[c]:.3g} "
                                f"(> {tol:g}): the truth renders do not reproduce the published rows")
    return out


def _eq(table, column: str, value):
    import pyarrow.compute as pc

    return pc.equal(table.column(column).cast("string"), value)


def merge_tables(out: Path, configs: list[dict], meas, pert, manifest: dict, methods, columns: tuple[str, ...],
                 paired: tuple[str, ...]) -> None:
    """Replace the rows of ``configs`` in ``out``'s three tables by the new ones (other configurations and tables
    untouched; each file written to a temporary sibling, then renamed) and add the command to ``budget.json``
    under ``incremental``. ``methods``: replace only these methods' measurement rows of ``configs`` (keep the
    configuration and perturbation tables, whose draws the new runs must repeat: :func:`paired_check`)."""
    import pyarrow as pa
    import pyarrow.compute as pc
    import pyarrow.parquet as pq

    new_cfg = _config_table(configs)
    names = new_cfg.column("config").combine_chunks()
    tables = {n: pq.read_table(Path(out) / TABLES / f"{n}.parquet") for n in (MEASUREMENTS, CONFIGS, PERTURBATIONS)}
    drop = {n: pc.is_in(t.column("config").cast(pa.string()), value_set=names) for n, t in tables.items()}
    new = {MEASUREMENTS: meas.select(list(columns)), CONFIGS: new_cfg, PERTURBATIONS: pert}
    if methods:
        old = tables[MEASUREMENTS]
        mine = pc.is_in(old.column("method").cast(pa.string()), value_set=pa.array(list(methods), pa.string()))
        paired = paired_check(old.filter(pc.and_(drop[MEASUREMENTS], pc.invert(mine))), new[MEASUREMENTS], paired)
        _same_draws(tables[PERTURBATIONS].filter(drop[PERTURBATIONS]), pert)
        drop = {MEASUREMENTS: pc.and_(drop[MEASUREMENTS], mine)}
        manifest = {**manifest, "methods": list(methods), "paired_max_abs_diff": paired}
    merged = {}
    for name, d in drop.items():
        keep = tables[name].filter(pc.invert(d))
        add = new[name].select(keep.column_names) if name != PERTURBATIONS else new[name]
        merged[name] = pa.concat_tables([keep, add], promote_options="default")
    for name, table in merged.items():
        write_compact_replacing(table, Path(out) / TABLES / f"{name}.parquet")
    mpath = Path(out) / MANIFEST
    man = json.loads(mpath.read_text(encoding="utf-8"))
    man.setdefault("incremental", []).append({**manifest, "configs": [c["config"] for c in configs]})
    mpath.write_text(json.dumps(man, indent=2, sort_keys=True) + "\n", encoding="utf-8")


def _same_draws(old, new) -> None:
    """UserError unless ``new``'s perturbation rows equal ``old``'s, per (config, run)."""
    cols = sorted((set(old.column_names) & set(new.column_names)) - {"campaign"})

    def rows(t):
        return sorted(json.dumps({c: t.column(c)[i].as_py() for c in cols}, sort_keys=True, default=str)
                      for i in range(t.num_rows))

    if rows(old) != rows(new):
        raise UserError("--methods: the new runs drew other knowledge errors than the table's (not the same seeds "
                        "or scenario): refusing to merge unpaired rows")
