"""Why Retina is not at the CRLB on exact models: its template sampling, measured (:mod:`.runner`).

With every error source off (McEwen truth = the onboard law, exact maplets, no knowledge error, no sensor
noise) the remaining error is deterministic: the template predicted from the maplet differs from the truth
image. Retina's template takes k × k point samples per pixel (``supersample``, the lab's default 3); the truth
is box-filtered by the renderer (``render.spp`` random sub-pixel samples). This probe measures ``retina`` and
``retina_refined`` on the budget's all-off truth set with k = 1, 3 and 6, everything else as in the budget's
all-off configuration (a-priori pose exact, search distance the runner's minimum), and keeps the rows in
``tables/budget_supersample.parquet``; the report turns them into ``budget_supersample.csv`` (per-landmark
bias rms with a cluster-bootstrap interval over landmark-frames). k = 3 reproduces the budget's all-off rows.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from renderlab.campaign.cache import cached_truthset
from renderlab.campaign.perturb import draw_perturbation
from renderlab.files.truthset import TruthSet
from renderlab.measurement.runner import MeasureOptions, measure_truthset
from renderlab.scenario import scenario_from_dict, truth_dict
from renderlab.sensor.model import SensorOptions
from renderlab.stats.bootstrap import cluster_bootstrap
from renderlab.studies.retina_vs_spc.run import BelievedTruthSet
from renderlab.worlds.ev5.catalog import read_catalog

SUPERSAMPLE = (1, 3, 6)
PROBE = "budget_supersample"


def probe_table(all_off: dict, base_dir: Path, workdir: Path, methods=("retina", "retina_refined")):
    """Rows of every method and k of :data:`SUPERSAMPLE` on the all-off truth set (module docstring)."""
    import pyarrow as pa


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


def probe_rows(table, n_boot: int = 1000, seed: int = 20) -> list[dict]:
    """Per method and k: results, per-landmark bias rms (both axes; all-off rows are deterministic, so the
    error of each landmark-frame is its bias) with a 95 % cluster-bootstrap interval over landmark-frames."""
    d = {c: np.asarray(table.column(c).to_pylist()) for c in table.column_names}
    out = []
    for m in dict.fromkeys(d["method"]):
        for k in SUPERSAMPLE:
            sel = (d["method"] == m) & (d["supersample"] == k) & d["truth_visible"].astype(bool)
            e = np.concatenate([d["err_s"][sel], d["err_l"][sel]]).astype(float)
            clu = np.concatenate([d["frame"][sel] * 1_000_000 + d["item"][sel]] * 2)
            ok = np.isfinite(e) & (np.abs(e) <= 1.0)
            iv = cluster_bootstrap(e[ok], clu[ok], "rms", n_boot=n_boot, rng=seed, cluster_name="landmark-frames")
            out.append({"method": m, "supersample": int(k), "results": int(ok.sum()), "bias_rms": iv.estimate,
                        "bias_rms_lo": iv.lo, "bias_rms_hi": iv.hi})
    return out
