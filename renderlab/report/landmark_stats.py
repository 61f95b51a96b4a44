"""Statistics of landmark measurement tables for reports: bias, robust σ, std, gross-error and no-result rates per
method and axis, each with a **cluster-bootstrap** interval, the no-result reasons, and paired comparisons.

Correlation structure: a landmark seen in the same frame over many runs shares its terrain, its truth image and its
mapping error; only the beliefs and the sensor noise change between runs. Rows of one (frame, landmark) are therefore
correlated, and the intervals resample whole **landmark-frames** (:func:`renderlab.stats.bootstrap.cluster_bootstrap`,
percentile intervals, seeded: the same table gives the same numbers). i.i.d. intervals on such data are too narrow
(``tests/test_bootstrap_coverage.py`` measures 37 % coverage for a nominal 95 % at intra-cluster correlation 0.5).

Robust statistics: robust σ = 1.4826 · MAD; the robust 2×2 covariance of (Δs, Δl) for the ellipses is the
Gnanadesikan–Kettenring estimator on MAD scales, centred at the component-wise median.
"""

from __future__ import annotations

import math

import numpy as np

from renderlab.stats.bootstrap import MAD_TO_SIGMA, cluster_bootstrap, cluster_bootstrap_rate, paired_difference

CLUSTERS = "landmark-frames"
N_BOOT_CLOSED, N_BOOT_RESAMPLED = 2000, 600


def _col(t, name, dtype=float):
    return np.asarray(t.column(name).to_numpy(zero_copy_only=False), dtype)


DEFAULT_CLUSTERS = ("frame", "item")


def cluster_ids(table, keys: tuple[str, ...] = DEFAULT_CLUSTERS) -> np.ndarray:
    """One integer per distinct combination of the ``keys`` columns: the cluster of each row (default: the
    landmark-frame, for studies whose runs share one truth render)."""
    cols = [np.asarray(table.column(k).to_numpy(zero_copy_only=False)) for k in keys]
    return np.unique(np.rec.fromarrays(cols), return_inverse=True)[1].ravel()


def cluster_name(keys: tuple[str, ...]) -> str:
    return CLUSTERS if tuple(keys) == DEFAULT_CLUSTERS else "distinct " + " × ".join(keys)


def has_result(table) -> np.ndarray:
    return _col(table, "has_result", bool) & np.isfinite(_col(table, "err_s")) & np.isfinite(_col(table, "err_l"))


def has_truth(table) -> np.ndarray:
    """Rows whose truth pixel is known (the scored population; a landmark without truth is not a failure)."""
    return np.isfinite(_col(table, "truth_s")) & np.isfinite(_col(table, "truth_l"))


def robust_sigma(x) -> float:
    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    return float(MAD_TO_SIGMA * np.median(np.abs(x - np.median(x)))) if x.size else math.nan


def robust_cov(x, y) -> tuple[np.ndarray, np.ndarray]:
    """(centre (2,), covariance (2, 2)): component-wise median and the Gnanadesikan–Kettenring covariance
    ``cov = ¼ (σ(u)² − σ(v)²)·σx σy`` with u, v = x/σx ± y/σy and σ the MAD scale."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    sx, sy = robust_sigma(x), robust_sigma(y)
    c = np.array([np.median(x), np.median(y)])
    if not (sx > 0 and sy > 0):
        return c, np.diag([sx * sx, sy * sy])
    u, v = x / sx + y / sy, x / sx - y / sy
    rho = (robust_sigma(u) ** 2 - robust_sigma(v) ** 2) / (robust_sigma(u) ** 2 + robust_sigma(v) ** 2)
    cxy = float(np.clip(rho, -0.999, 0.999)) * sx * sy
    return c, np.array([[sx * sx, cxy], [cxy, sy * sy]])


def _iv(prefix: str, iv) -> dict:
    return {prefix: iv.estimate, f"{prefix}_lo": iv.lo, f"{prefix}_hi": iv.hi}


def method_summary(table, mask=None, *, gross_px: float = 1.0, confidence: float = 0.95, seed: int = 0,
                   subset: str = "all", cluster_keys: tuple[str, ...] = DEFAULT_CLUSTERS) -> list[dict]:
    """Rows per (method, axis) among the rows with a truth: counts, bias, robust σ, std, gross-error rate (|err| >
    ``gross_px`` on that axis among results) and no-result rate, each with a cluster-bootstrap interval (module
    docstring)."""
    mask = (np.ones(table.num_rows, bool) if mask is None else np.asarray(mask, bool)) & has_truth(table)
    meth, cl, ok = _col(table, "method", object), cluster_ids(table, cluster_keys), has_result(table)
    cname = cluster_name(cluster_keys)
    rows = []
    for m in sorted(set(meth[mask])):
        sel = mask & (meth == m)
        nores = cluster_bootstrap_rate(~ok[sel], cl[sel], confidence=confidence, n_boot=N_BOOT_CLOSED, rng=seed,
                                       cluster_name=cname)
        for axis in ("s", "l"):
            e, c = _col(table, f"err_{axis}")[sel & ok], cl[sel & ok]
            common = dict(confidence=confidence, rng=seed, cluster_name=cname)
            row = {"subset": subset, "method": m, "axis": axis, "n_rows": int(sel.sum()), "n_result": int(e.size),
                   "n_clusters": int(len(np.unique(cl[sel]))),
                   **_iv("bias_px", cluster_bootstrap(e, c, "mean", n_boot=N_BOOT_CLOSED, **common)),
                   **_iv("robust_sigma_px", cluster_bootstrap(e, c, "robust_sigma", n_boot=N_BOOT_RESAMPLED, **common)),
                   **_iv("std_px", cluster_bootstrap(e, c, "std", n_boot=N_BOOT_CLOSED, **common)),
                   **_iv("gross_rate", cluster_bootstrap_rate(np.abs(e) > gross_px, c, n_boot=N_BOOT_CLOSED,
                                                              **common)),
                   **_iv("no_result_rate", nores)}
            if f"crlb_{axis}" in table.column_names:
                cr = _col(table, f"crlb_{axis}")[sel & ok]
                cr = cr[np.isfinite(cr)]
                row["crlb_rms_px"] = float(np.sqrt(np.mean(cr * cr))) if cr.size else math.nan
                row["robust_sigma_over_crlb"] = (row["robust_sigma_px"] / row["crlb_rms_px"]
                                                 if cr.size and row["crlb_rms_px"] > 0 else math.nan)
            rows.append(row)
    return rows


def reason_counts(table, mask=None, subset: str = "all") -> list[dict]:
    """Rows per (method, reason) among the rows with a truth: count and share of the method's rows (``ok``
    included)."""
    mask = (np.ones(table.num_rows, bool) if mask is None else np.asarray(mask, bool)) & has_truth(table)
    meth, reason = _col(table, "method", object), _col(table, "reason", object)
    rows = []
    for m in sorted(set(meth[mask])):
        sel = mask & (meth == m)
        for r in sorted(set(reason[sel]), key=lambda r: (r != "ok", r)):
            k = int((sel & (reason == r)).sum())
            rows.append({"subset": subset, "method": m, "reason": r, "rows": k, "share": k / max(int(sel.sum()), 1)})
    return rows


def paired_comparison(table, mask=None, *, confidence: float = 0.95, seed: int = 0, subset: str = "all",
                      cluster_keys: tuple[str, ...] = DEFAULT_CLUSTERS) -> list[dict]:
    """For each pair of methods (A, B): mean of |err_B| − |err_A| (radial error, px) over the rows where both
    measured the same landmark in the same frame and run, with a cluster-bootstrap interval; and the share of
    those rows where B's error is smaller."""
    mask = np.ones(table.num_rows, bool) if mask is None else np.asarray(mask, bool)
    meth = _col(table, "method", object)
    key = (_col(table, "run", np.int64) * 1_000_003 + _col(table, "frame", np.int64)) * 1_000_003 \
        + _col(table, "item", np.int64)
    rad = np.hypot(_col(table, "err_s"), _col(table, "err_l"))
    ok, cl = has_result(table) & mask, cluster_ids(table, cluster_keys)
    by = {}
    for m in sorted(set(meth[mask])):
        s = ok & (meth == m)
        by[m] = dict(zip(key[s].tolist(), zip(rad[s].tolist(), cl[s].tolist())))
    rows = []
    names = sorted(by)
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            common = sorted(set(by[a]) & set(by[b]))
            if not common:
                continue
            ea = np.array([by[a][k][0] for k in common])
            eb = np.array([by[b][k][0] for k in common])
            c = np.array([by[a][k][1] for k in common])
            iv = paired_difference(eb, ea, c, "mean", confidence=confidence, n_boot=N_BOOT_CLOSED, rng=seed,
                                   cluster_name=cluster_name(cluster_keys))
            rows.append({"subset": subset, "method_a": a, "method_b": b, "n_pairs": len(common),
                         "mean_abs_err_b_minus_a_px": iv.estimate, "lo": iv.lo, "hi": iv.hi,
                         "share_b_smaller": float(np.mean(eb < ea))})
    return rows


BREAKDOWNS = ("phase_deg", "gsd_ratio", "shadow_fraction", "albedo_contrast", "range_m")


def breakdown(table, column: str, bins: int = 4, *, confidence: float = 0.95, seed: int = 0,
              cluster_keys: tuple[str, ...] = DEFAULT_CLUSTERS) -> list[dict]:
    """:func:`method_summary` rows per quantile bin of ``column`` (keys ``by``, ``bin``, ``lo``, ``hi``,
    ``center`` = the bin's median); empty when the column is absent or has no finite value."""
    if column not in table.column_names:
        return []
    v = _col(table, column)
    fin = np.isfinite(v)
    if not fin.any():
        return []
    edges = np.unique(np.quantile(v[fin], np.linspace(0, 1, bins + 1)))
    if len(edges) < 2:
        edges = np.array([v[fin].min(), v[fin].max()])
    idx = np.clip(np.searchsorted(edges, v, side="right") - 1, 0, len(edges) - 2)
    rows = []
    for b in range(len(edges) - 1):
        mask = fin & (idx == b)
        if mask.any():
            keys = {"by": column, "bin": b, "lo": float(edges[b]), "hi": float(edges[b + 1]),
                    "center": float(np.median(v[mask]))}
            rows += [{**keys, **r} for r in method_summary(table, mask, confidence=confidence, seed=seed,
                                                           cluster_keys=cluster_keys)]
    return rows
