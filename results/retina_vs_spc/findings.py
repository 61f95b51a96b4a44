"""Findings of a ``retina_vs_spc`` campaign: SPC's bias and Retina's noise with confidence intervals.

    .venv/bin/python results/retina_vs_spc/findings.py CAMPAIGN_DIR [--out findings.csv]

Rows are one landmark in one frame of one run. The errors of one landmark in one frame are correlated
over runs (same terrain, same truth image; only the beliefs and the noise change), so the 95 % intervals
here are a *cluster bootstrap* over landmark-frames (2000 resamples for mean/std, 400 for median/MAD; seeded): the i.i.d. intervals of
``summary.csv`` are narrower than the evidence allows. Per method and axis: bias (mean), noise (std),
median, MAD·1.4826, share of no result, share of gross errors (|err| > 1 px among results); and the paired difference |err_spc| − |err_retina| on the rows
where both returned a result. Two populations: all rows with a truth, and the pre-set "well-measured"
subset (0.5 ≤ gsd_ratio ≤ 2, shadow_fraction ≤ 0.05, truth visible).
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

import numpy as np

from renderlab.stats.bootstrap import cluster_bootstrap


def _load(campaign: Path) -> dict:
    import pyarrow as pa
    import pyarrow.parquet as pq

    parts = [pq.read_table(p) for p in sorted((campaign / "runs").glob("*/measurements.parquet"))]
    t = pa.concat_tables(parts, promote_options="default").to_pydict()
    return {k: np.asarray(v) for k, v in t.items()}


def _ci(values, clusters, stat, rng, n_boot=2000) -> tuple[float, float, float]:
    """(estimate, 2.5 %, 97.5 %) of ``stat`` under a cluster bootstrap over landmark-frames."""
    iv = cluster_bootstrap(values, clusters, stat, n_boot=n_boot, rng=rng, cluster_name="landmark-frames")
    return iv.estimate, iv.lo, iv.hi


def findings(t: dict, subset: str, seed: int = 0) -> list[dict]:
    rng = np.random.default_rng(seed)
    has_truth = np.isfinite(t["truth_s"]) & np.isfinite(t["truth_l"]) & t["truth_visible"].astype(bool)
    sel = has_truth.copy()
    if subset == "well_measured":
        sel &= (t["gsd_ratio"] >= 0.5) & (t["gsd_ratio"] <= 2.0) & (t["shadow_fraction"] <= 0.05)
    ok = np.isfinite(t["err_s"]) & np.isfinite(t["err_l"])
    key = np.array([f"{f}:{i}" for f, i in zip(t["frame"], t["item"])])
    rows = []
    for m in ("retina", "spc"):
        ms = sel & (t["method"] == m)
        res = ms & ok
        nores = float(np.mean(~ok[ms])) if ms.any() else np.nan
        big = np.hypot(t["err_s"][res], t["err_l"][res]) > 1.0
        gross = float(np.mean(big)) if res.any() else np.nan
        for ax in ("s", "l"):
            e = t[f"err_{ax}"][res]
            c = key[res]
            row = {"subset": subset, "method": m, "axis": ax, "n_rows": int(ms.sum()), "n_result": int(res.sum()),
                   "no_result_rate": nores, "gross_rate": gross}
            for name, stat, nb in (("bias", "mean", 2000), ("noise", "std", 2000), ("median", "median", 400),
                                   ("mad", "robust_sigma", 400)):
                row[name], row[f"{name}_lo"], row[f"{name}_hi"] = _ci(e, c, stat, rng, nb) if len(e) > 2 else (np.nan,) * 3
            rows.append(row)
    both = {}
    for m in ("retina", "spc"):
        ms = sel & ok & (t["method"] == m)
        both[m] = {(r, k): np.hypot(es, el) for r, k, es, el in zip(t["run"][ms], key[ms], t["err_s"][ms], t["err_l"][ms])}
    common = sorted(set(both["retina"]) & set(both["spc"]))
    if common:
        d = np.array([both["spc"][k] - both["retina"][k] for k in common])
        cl = np.array([k[1] for k in common])
        est, lo, hi = _ci(d, cl, "mean", rng)
        med, mlo, mhi = _ci(d, cl, "median", rng, 400)
        rows.append({"subset": subset, "method": "spc-retina", "axis": "|err|", "n_rows": len(common),
                     "n_result": len(common), "bias": est, "bias_lo": lo, "bias_hi": hi,
                     "median": med, "median_lo": mlo, "median_hi": mhi})
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("campaign", type=Path)
    ap.add_argument("--out", type=Path, default=None)
    a = ap.parse_args(argv)
    t = _load(a.campaign)
    rows = findings(t, "all") + findings(t, "well_measured")
    cols = ["subset", "method", "axis", "n_rows", "n_result", "no_result_rate", "gross_rate", "bias", "bias_lo", "bias_hi",
            "noise", "noise_lo", "noise_hi", "median", "median_lo", "median_hi", "mad", "mad_lo", "mad_hi"]
    w = csv.DictWriter(open(a.out, "w", newline="") if a.out else sys.stdout, fieldnames=cols, extrasaction="ignore")
    w.writeheader()
    for r in rows:
        w.writerow({k: (f"{v:.4f}" if isinstance(v, float) else v) for k, v in r.items()})
    print(f"runs: {len(np.unique(t['run']))}, rows: {len(t['run'])}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
