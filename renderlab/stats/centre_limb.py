"""Scoring of centre/limb tables (:mod:`renderlab.contracts.centre_limb_table`): the kind's ``scorer``.

Per row with a result (:func:`derived`):

* centre error ``err_s``, ``err_l`` = measured − true projected centre (px);
* line-of-sight error ``los_err_urad`` = ``1e6·|err|/fx`` (the angle the centre error subtends; within 0.1 % of the
  exact angle within 3° of the boresight);
* relative range error ``range_err_rel`` = measured / true − 1 (methods that give a range);
* NEES of the method's **own** covariance: ``nees_centre`` = ``eᵀ C⁻¹ e`` (2 dof, C = ``cov_*`` px²) and
  ``nees_position`` = ``(r − r_true)ᵀ P⁻¹ (r − r_true)`` (3 dof, ``r_true`` = true range × true line of sight).

Summary (:func:`score_table`), per method, for all rows and per photometric law (``law`` column when present):

* **bias**: the mean error (``err_s``, ``err_l``, ``range_err_rel``); **noise**: the RMS of the residual about each
  grid cell's own mean, scaled by √(n_c/(n_c − 1)) (the within-cell scatter: Monte Carlo noise, the bias removed);
  ``los_rms_urad`` the total RMS line-of-sight error;
* **ANEES** = mean NEES with the two-sided χ² band ``[χ²_{kN}(α/2), χ²_{kN}(1−α/2)]/N`` of N independent
  k-dof values and PASS/FAIL (``inside``); beside it the median NEES (a consistent covariance gives the χ²_k
  median, 1.386 for k = 2 and 2.366 for k = 3; the mean is dominated by the worst images);
* ``result_rate`` and, per no-result reason, its rate.

Intervals: percentile **cluster bootstrap** over grid cells (``cell``: the images of one cell share a geometry and
its bias, draws within it are independent; :func:`renderlab.stats.bootstrap.cluster_bootstrap`), 2000 resamples,
seed 0.
"""

from __future__ import annotations

import math

import numpy as np

from renderlab.stats.bootstrap import cluster_bootstrap, cluster_bootstrap_rate

#: quantity → (unit, what) of the summary rows
QUANTITIES = {
    "result_rate": ("—", "share of images with a result"),
    "bias_s": ("px", "mean centre error, sample"), "bias_l": ("px", "mean centre error, line"),
    "noise_s": ("px", "within-cell RMS scatter, sample"), "noise_l": ("px", "within-cell RMS scatter, line"),
    "los_rms_urad": ("µrad", "RMS line-of-sight error"),
    "bias_range_rel": ("—", "mean relative range error"), "noise_range_rel": ("—", "within-cell relative range scatter"),
    "anees_centre": ("—", "ANEES of the centre covariance (2 dof)"),
    "anees_position": ("—", "ANEES of the position covariance (3 dof)"),
    "median_nees_centre": ("—", "median NEES of the centre covariance (χ²₂ median 1.386)"),
    "median_nees_position": ("—", "median NEES of the position covariance (χ²₃ median 2.366)"),
}


def _np(table, name, dtype=float) -> np.ndarray:
    return np.asarray(table.column(name).to_numpy(zero_copy_only=False), dtype)


def _nees(e: np.ndarray, C: np.ndarray) -> np.ndarray:
    """Row-wise ``eᵀ C⁻¹ e`` (NaN where C is missing or not positive definite)."""
    out = np.full(len(e), np.nan)
    for i in range(len(e)):
        if np.all(np.isfinite(e[i])) and np.all(np.isfinite(C[i])):
            try:
                L = np.linalg.cholesky(C[i])
            except np.linalg.LinAlgError:
                continue
            z = np.linalg.solve(L, e[i])
            out[i] = float(z @ z)
    return out


def derived(table) -> dict[str, np.ndarray]:
    """The per-row quantities of the module docstring, plus ``method``, ``cell``, ``law``, ``ok`` and ``reason``."""
    ok = _np(table, "has_result", bool)
    e = np.column_stack([_np(table, "centre_s") - _np(table, "true_centre_s"),
                         _np(table, "centre_l") - _np(table, "true_centre_l")])
    e[~ok] = np.nan
    C = np.stack([_np(table, "cov_ss"), _np(table, "cov_sl"), _np(table, "cov_sl"), _np(table, "cov_ll")], 1)
    r = np.column_stack([_np(table, f"r_{a}") for a in "xyz"])
    r_true = _np(table, "true_range_m")[:, None] * np.column_stack([_np(table, f"true_los_{a}") for a in "xyz"])
    P = np.stack([_np(table, f"cov_r_{k}") for k in ("xx", "xy", "xz", "xy", "yy", "yz", "xz", "yz", "zz")], 1)
    rng_rel = _np(table, "range_m") / _np(table, "true_range_m") - 1.0
    rng_rel[~ok | ~np.all(np.isfinite(r), axis=1)] = np.nan
    law = (np.asarray(table.column("law").to_pylist(), object) if "law" in table.column_names
           else np.full(table.num_rows, "", object))
    return {"method": np.asarray(table.column("method").to_pylist(), object), "cell": _np(table, "cell", np.int64),
            "law": law, "ok": ok, "reason": np.asarray([str(x) for x in table.column("reason").to_pylist()], object),
            "err_s": e[:, 0], "err_l": e[:, 1], "los_err_urad": 1e6 * np.hypot(e[:, 0], e[:, 1]) / _np(table, "fx"),
            "range_err_rel": rng_rel, "nees_centre": _nees(e, C.reshape(-1, 2, 2)),
            "nees_position": _nees(np.where(ok[:, None], r - r_true, np.nan), P.reshape(-1, 3, 3)),
            "phase_deg": _np(table, "phase_deg"),
            "range_nominal_m": (_np(table, "range_nominal_m") if "range_nominal_m" in table.column_names
                                else _np(table, "true_range_m"))}


def within_cell(values: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Residuals about each cell's mean, scaled by √(n_c/(n_c − 1)) (NaN in cells with < 2 values)."""
    out = np.full(len(values), np.nan)
    for c in np.unique(cells):
        s = (cells == c) & np.isfinite(values)
        n = int(s.sum())
        if n >= 2:
            out[s] = (values[s] - values[s].mean()) * math.sqrt(n / (n - 1))
    return out


def chi2_band(k: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """Two-sided band of the mean of ``n`` independent χ²_k values."""
    from scipy.stats import chi2

    if n < 1:
        return math.nan, math.nan
    a = (1.0 - confidence) / 2.0
    return float(chi2.ppf(a, k * n) / n), float(chi2.ppf(1.0 - a, k * n) / n)


def _row(method, group, quantity, iv, **more) -> dict:
    unit, what = QUANTITIES.get(quantity, ("—", quantity.replace("_", " ")))
    return {"method": method, "group": group, "quantity": quantity, "unit": unit, "estimate": iv.estimate,
            "lo": iv.lo, "hi": iv.hi, "n": iv.n, "n_clusters": iv.n_clusters, "band_lo": math.nan,
            "band_hi": math.nan, "inside": None, "what": what, **more}


def summarize(d: dict, sel: np.ndarray, method: str, group: str, confidence: float) -> list[dict]:
    """Summary rows of the rows ``sel`` of :func:`derived`'s ``d``."""
    cl = d["cell"][sel]
    kw = {"confidence": confidence, "cluster_name": "grid cells"}
    rows = [_row(method, group, "result_rate", cluster_bootstrap_rate(d["ok"][sel], cl, **kw))]
    for q, col, stat in (("bias_s", "err_s", "mean"), ("bias_l", "err_l", "mean"),
                         ("los_rms_urad", "los_err_urad", "rms"), ("bias_range_rel", "range_err_rel", "mean")):
        rows.append(_row(method, group, q, cluster_bootstrap(d[col][sel], cl, stat, **kw)))
    for q, col in (("noise_s", "err_s"), ("noise_l", "err_l"), ("noise_range_rel", "range_err_rel")):
        rows.append(_row(method, group, q, cluster_bootstrap(within_cell(d[col][sel], cl), cl, "rms", **kw)))
    for q, col, k in (("anees_centre", "nees_centre", 2), ("anees_position", "nees_position", 3)):
        iv = cluster_bootstrap(d[col][sel], cl, "mean", **kw)
        lo, hi = chi2_band(k, iv.n, confidence)
        rows.append(_row(method, group, q, iv, band_lo=lo, band_hi=hi,
                         inside=(bool(lo <= iv.estimate <= hi) if iv.n else None)))
        rows.append(_row(method, group, f"median_{col}", cluster_bootstrap(d[col][sel], cl, "median", **kw)))
    for reason in sorted(set(d["reason"][sel]) - {"ok"}):
        iv = cluster_bootstrap_rate(d["reason"][sel] == reason, cl, **kw)
        rows.append(_row(method, group, f"rate_{reason}", iv, what=f"share of images with no result: {reason}"))
    return rows


def score_table(table, *, confidence: float = 0.95) -> list[dict]:
    """The kind's scorer: summary rows per method, all rows (``group`` "all") and per law (module docstring)."""
    d = derived(table)
    out = []
    for m in sorted(set(d["method"])):
        sm = d["method"] == m
        out += summarize(d, sm, m, "all", confidence)
        for law in sorted(set(d["law"][sm]) - {""}):
            out += summarize(d, sm & (d["law"] == law), m, str(law), confidence)
    return out


def cell_table(d: dict) -> list[dict]:
    """Per method and cell: the cell's grid values, result count, mean centre/range errors and their standard
    deviations, mean NEES, the median |centre error| (px), the share of images with |centre error| > 3 px and the
    median relative range error."""
    rows = []
    e = np.hypot(d["err_s"], d["err_l"])

    def med(v):
        return float(np.median(v[np.isfinite(v)])) if np.isfinite(v).any() else math.nan

    for m in sorted(set(d["method"])):
        for c in np.unique(d["cell"][d["method"] == m]):
            s = (d["method"] == m) & (d["cell"] == c)
            ok = d["ok"][s]

            def mean(col, s=s):
                v = d[col][s]
                return float(np.nanmean(v)) if np.isfinite(v).any() else math.nan

            def sd(col, s=s):
                v = d[col][s]
                v = v[np.isfinite(v)]
                return float(np.std(v, ddof=1)) if len(v) > 1 else math.nan

            rows.append({"method": m, "cell": int(c), "law": str(d["law"][s][0]),
                         "range_nominal_m": float(d["range_nominal_m"][s][0]),
                         "phase_deg": float(np.nanmean(d["phase_deg"][s])), "n": int(s.sum()), "n_ok": int(ok.sum()),
                         "bias_s_px": mean("err_s"), "bias_l_px": mean("err_l"), "sd_s_px": sd("err_s"),
                         "sd_l_px": sd("err_l"), "bias_range_rel": mean("range_err_rel"),
                         "sd_range_rel": sd("range_err_rel"), "mean_nees_centre": mean("nees_centre"),
                         "mean_nees_position": mean("nees_position"), "median_err_px": med(e[s]),
                         "share_err_over_3px": (float(np.mean(e[s][np.isfinite(e[s])] > 3.0))
                                                if np.isfinite(e[s]).any() else math.nan),
                         "median_range_err_rel": med(d["range_err_rel"][s])})
    return rows
