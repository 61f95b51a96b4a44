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


def _load(campaign: Path) -> dict:
    import pyarrow as pa
    import pyarrow.parquet as pq

    parts = [pq.read_table(p) for p in sorted((campaign / "runs").glob("*/measurements.parquet"))]
    t = pa.concat_tables(parts, promote_options="default").to_pydict()
    return {k: np.asarray(v) for k, v in t.items()}


def _cluster_ci(values, clusters, stat, rng, n_boot=2000):
    """(estimate, 2.5 %, 97.5 %) of ``stat`` ("mean", "std" or a function) under a cluster bootstrap."""
    uniq, inv = np.unique(clusters, return_inverse=True)
    draws = rng.multinomial(len(uniq), np.full(len(uniq), 1.0 / len(uniq)), size=n_boot)  # cluster counts
    if stat in ("mean", "std"):  # closed form from per-cluster sums
        n = np.bincount(inv, minlength=len(uniq)).astype(float)
        s1 = np.bincount(inv, values, minlength=len(uniq))
        s2 = np.bincount(inv, values * values, minlength=len(uniq))
        N, S1, S2 = draws @ n, draws @ s1, draws @ s2
        if stat == "mean":
            est, boots = values.mean(), S1 / N
        else:
            est, boots = values.std(ddof=1), np.sqrt(np.clip(S2 - S1 * S1 / N, 0, None) / np.maximum(N - 1, 1))
    else:
        order = np.argsort(inv, kind="stable")
        starts = np.r_[0, np.cumsum(np.bincount(inv, minlength=len(uniq)))]
        groups = [order[starts[k]:starts[k + 1]] for k in range(len(uniq))]
        est = stat(values)
        boots = np.array([stat(values[np.concatenate([np.repeat(groups[k], c) for k, c in enumerate(row) if c])])
                          for row in draws[:400]])
    lo, hi = np.percentile(boots, [2.5, 97.5])
    return float(est), float(lo), float(hi)


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
            for name, fn in (("bias", "mean"), ("noise", "std"), ("median", np.median),
                             ("mad", lambda x: 1.4826 * np.median(np.abs(x - np.median(x))))):
                row[name], row[f"{name}_lo"], row[f"{name}_hi"] = _cluster_ci(e, c, fn, rng) if len(e) > 2 else (np.nan,) * 3
            rows.append(row)
    both = {}
    for m in ("retina", "spc"):
        ms = sel & ok & (t["method"] == m)
        both[m] = {(r, k): np.hypot(es, el) for r, k, es, el in zip(t["run"][ms], key[ms], t["err_s"][ms], t["err_l"][ms])}
    common = sorted(set(both["retina"]) & set(both["spc"]))
    if common:
        d = np.array([both["spc"][k] - both["retina"][k] for k in common])
        cl = np.array([k[1] for k in common])
        est, lo, hi = _cluster_ci(d, cl, "mean", rng)
        med, mlo, mhi = _cluster_ci(d, cl, np.median, rng)
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
