"""One-at-a-time (OAT) error budgets of a campaign study: which error source adds how much.

Every source is switched on alone (its scenario keys at the base scenario's values, every other source's keys at
their "off" values), beside "all off" and "all on" (the base scenario) and any extra configuration the study adds.
The switches are scenario keys, nothing else: :func:`oat_configs` builds each configuration's scenario dict.
:func:`run_configs` runs every configuration's runs in worker processes with common random numbers (every
configuration uses the same campaign seed and run indices, so runs ``i`` of two configurations share their noise and
draws); a configuration with no random draw runs once. The first run of each distinct truth goes first, so no two
workers render the same truth at once. The tables are :mod:`renderlab.campaign.oat_tables`, the statistics
:mod:`renderlab.stats.oat_budget`, the figure :mod:`renderlab.report.budget_figure`.
"""

from __future__ import annotations

import copy
import hashlib
import json
import sys
import time
from pathlib import Path

from renderlab.errors import UserError
from renderlab.scenario import truth_dict


def get_key(d: dict, dotted: str):
    """``d["a"]["b"]`` for ``"a.b"`` (KeyError/TypeError when a level is missing)."""
    for k in dotted.split("."):
        d = d[k]
    return d


def set_key(d: dict, dotted: str, value) -> None:
    """Set ``"a.b"`` of ``d`` to a copy of ``value``, making the tables on the way."""
    *head, last = dotted.split(".")
    for k in head:
        d = d.setdefault(k, {})
    d[last] = copy.deepcopy(value)


def oat_configs(base: dict, sources: dict[str, tuple[str, tuple[str, ...]]], off: dict, *, fixed: dict,
                extra: tuple = (), all_off: str = "every source off", all_on: str = "every source on",
                need: str = "") -> list[dict]:
    """The configurations ``all_off``, one per source (that source's keys at the base value, the others ``off``),
    ``all_on`` (the base scenario) and ``extra`` ((name, description, overrides) at all off, source ``""``) →
    ``[{"config", "source", "description", "overrides", "scenario"}]``.

    ``sources``: source → (description, dotted keys restored from ``base`` to switch it on); ``off``: every
    source's keys → its "off" value; ``fixed``: keys set in every configuration (the methods). ``need`` names the
    base scenario a study needs, in the error when ``base`` lacks a source key.
    """
    for keys in (k for _, ks in sources.values() for k in ks):
        try:
            get_key(base, keys)
        except (KeyError, TypeError):
            raise UserError(f"error budget: the base scenario has no {keys} ({need})") from None
    out = []

    def add(name, source, desc, overrides):
        sc = copy.deepcopy(base)
        for k, v in {**overrides, **fixed}.items():
            set_key(sc, k, v)
        out.append({"config": name, "source": source, "description": desc, "overrides": overrides, "scenario": sc})

    add("all_off", "", all_off, dict(off))
    for src, (desc, keys) in sources.items():
        add(src, src, f"{desc} alone", {**off, **{k: get_key(base, k) for k in keys}})
    add("all_on", "", all_on, {})
    for name, desc, overrides in extra:
        add(name, "", desc, {**off, **overrides})
    return out


def has_draws(sc: dict, keys) -> bool:
    """Whether runs of scenario dict ``sc`` differ: any of the dotted ``keys`` (switches and σ's of random draws)
    true or non-zero (missing keys count as off)."""
    def value(k):
        try:
            return get_key(sc, k)
        except (KeyError, TypeError):
            return None
    return any(_nonzero(value(k)) for k in keys)


def _nonzero(v) -> bool:
    if isinstance(v, dict):
        return any(_nonzero(x) for x in v.values())
    if isinstance(v, (list, tuple)):
        return any(_nonzero(x) for x in v)
    return v is not None and float(v) != 0.0


def done_paths(task) -> tuple[Path, Path]:
    """Where a finished run of ``task`` is kept in the scratch folder (keyed by scenario content, seed, run)."""
    name, sc_dict, _, index, seed, workdir = task
    key = hashlib.sha256(json.dumps([sc_dict, seed, index], sort_keys=True).encode()).hexdigest()[:16]
    d = Path(workdir) / "budget_runs"
    return d / f"{name}_{index:03d}_{key}_m.parquet", d / f"{name}_{index:03d}_{key}_p.parquet"


def tasks(configs, base_dir, runs, seed, workdir, stochastic) -> tuple[list, list]:
    """(first tasks: one per distinct truth, rest) of (config, scenario dict, base dir, run, seed, workdir); sets
    each configuration's ``runs`` (1 where ``stochastic(scenario)`` is false)."""
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


def run_configs(configs, worker, *, base_dir, runs: int, seed: int, workers: int, workdir, stochastic) -> tuple:
    """Run every task of ``configs`` through ``worker(task) → (config, run, measurements, perturbations, seconds)``
    in ``workers`` processes (progress on stderr) → (measurements, perturbations, wall seconds), the tables of every
    run concatenated."""
    import concurrent.futures as cf

    import pyarrow as pa

    first, rest = tasks(configs, base_dir, runs, seed, workdir, stochastic)
    total, done, t0 = len(first) + len(rest), 0, time.perf_counter()
    meas, pert = [], []
    with cf.ProcessPoolExecutor(max_workers=max(1, workers)) as pool:
        for batch in (first, rest):
            for name, i, m, p, dt in pool.map(worker, batch):
                done += 1
                meas.append(m)
                pert.append(p)
                print(f"[{done}/{total}] {name} run {i}: {m.num_rows} rows, {dt:.1f} s "
                      f"(elapsed {time.perf_counter() - t0:.0f} s)", file=sys.stderr, flush=True)
    wall = time.perf_counter() - t0
    return (pa.concat_tables(meas, promote_options="default"), pa.concat_tables(pert, promote_options="default"),
            wall)
