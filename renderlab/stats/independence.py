r"""Are the runs of a campaign independent? The share of the error common to all runs, and the χ² bands it implies,
from the filter and landmark tables alone (a descent campaign's, :mod:`renderlab.studies.descent_navigation`).

An ANEES band χ²(6N)/N assumes N independent runs. When part of the error is the same in every run (one map, one
set of truth images, a method's rendering error fixed by the geometry), the runs are correlated and the plain band
is too narrow. Per method and image:

* **landmark errors** (kept landmarks; per axis): the share of their mean square common to all runs,
  :math:`f = \sum_i n_i(\bar e_i^2 - s_i^2/n_i) / \sum_{i,j} e_{ij}^2` over the landmarks i measured in ≥ 2 runs
  (:math:`\bar e_i`, :math:`s_i^2` the mean and variance over its :math:`n_i` runs; :math:`\bar e_i^2 - s_i^2/n_i`
  is the unbiased estimate of the squared common part), clipped to [0, 1];
* **state errors**: the same share of the whitened errors :math:`\mathbf y = L^{-1}\mathbf e` (P = LLᵀ; NEES =
  |y|²): :math:`\rho = (|\bar{\mathbf y}|^2 - \mathrm{tr}\,\hat\Sigma_y/N) / \overline{|\mathbf y|^2}` (I1);
* **innovations** (meas − pred of the kept landmarks, per axis): the same share, ρ_ν (I2).

Model: :math:`\mathbf y_r = \mathbf c + \mathbf w_r`, a common part of variance ρ and independent parts of
variance 1 − ρ per dof. Then Var(ANEES/6) = (ρ² + (1 − ρ²)/N)/3, which is that of χ²(6M)/(6M) for

.. math::  N_{\mathrm{eff}} = \frac{N}{1 + (N-1)\rho^2}   \quad (I3)

(Satterthwaite's effective degrees of freedom: a NEES's correlation between runs is ρ²). The *effective* band is
χ²(6 N_eff)/(6 N_eff) for ANEES/6 and χ²(Σdof/(1 + (N−1)ρ_ν²)) scaled alike for ANIS/dof. It is reported **beside**
the plain band, never instead of it.
"""

from __future__ import annotations

import math
from collections import defaultdict

import numpy as np

from renderlab.stats.consistency import chi2_band_sum, columns, tracked

WHITE = tuple(f"white_{k}" for k in range(6))


def common_share(values: np.ndarray, groups: np.ndarray) -> float:
    """Share of the mean square of ``values`` common to all runs within each group (module docstring), [0, 1]."""
    v = np.asarray(values, float)
    ok = np.isfinite(v)
    v, groups = v[ok], np.asarray(groups)[ok]
    total = float(np.sum(v**2))
    if v.size < 2 or total <= 0:
        return math.nan
    by = defaultdict(list)
    for g, x in zip(groups.tolist(), v.tolist()):
        by[g].append(x)
    common = 0.0
    for xs in by.values():
        if len(xs) >= 2:
            a = np.asarray(xs)
            common += len(a) * (a.mean() ** 2 - a.var(ddof=1) / len(a))
    return float(min(max(common / total, 0.0), 1.0))


def state_common_share(y: np.ndarray) -> float:
    """ρ of eq. I1 from the whitened errors y (N, 6) of one image."""
    y = y[np.all(np.isfinite(y), 1)]
    n = len(y)
    if n < 2:
        return math.nan
    tot = float(np.mean(np.sum(y**2, 1)))
    common = float(np.sum(y.mean(0) ** 2) - np.trace(np.cov(y.T)) / n)
    return float(min(max(common / tot, 0.0), 1.0)) if tot > 0 else math.nan


def n_effective(n: int, rho: float) -> float:
    """N_eff of eq. I3 (N when ρ is not finite)."""
    if not math.isfinite(rho):
        return float(n)
    return float(n / (1.0 + (n - 1) * rho**2))


def landmark_shares(lc: dict, method: str, frame: int) -> dict:
    """Common shares of the landmark errors (s, l) and of the innovations (pooled s, l) of one method and image;
    ``lc``: columns of the landmark table (runs that kept track)."""
    k = (lc["method"] == method) & (lc["frame"] == frame) & lc["kept"]
    items = lc["item"][k]
    out = {f"common_share_err_{a}": common_share(lc[f"err_{a}"][k], items) for a in ("s", "l")}
    if "pred_s" in lc:
        nu = np.concatenate([lc["meas_s"][k] - lc["pred_s"][k], lc["meas_l"][k] - lc["pred_l"][k]])
        grp = np.concatenate([items * 2, items * 2 + 1])
        out["common_share_innov"] = common_share(nu, grp)
    return out


def tracked_landmarks(ftab, ltab):
    """The landmark rows of the (method, run) pairs that kept track (as the filter scores: :func:`renderlab.stats.consistency.tracked`)."""
    import pyarrow as pa


    ok = set(zip(tracked(ftab).column("method").to_pylist(), tracked(ftab).column("run").to_pylist()))
    keys = zip(ltab.column("method").to_pylist(), ltab.column("run").to_pylist())
    return ltab.filter(pa.array([k in ok for k in keys]))


def independence_rows(ftab, images: dict, ts_rows: list[dict]) -> list[dict]:
    """One row per method and image: ρ (eq. I1), ρ_ν (I2), the landmark shares, N_eff (I3) and the effective bands
    beside the plain ones of ``ts_rows`` (:func:`renderlab.studies.descent_navigation.scoring.timeseries`).
    ``images``: ``{(method, frame): row}`` with ``rho_state`` (:func:`state_common_share` of the image's whitened
    errors) and, where the landmarks were measured, the shares of :func:`landmark_shares`, over the runs that kept
    track."""
    c = columns(tracked(ftab), ("method", "frame", "nees", "nis", "dof"))
    out = []
    for r in ts_rows:
        m, k = r["method"], r["frame"]
        if k < 0:
            continue
        s = (c["method"] == m) & (c["frame"] == k) & np.isfinite(c["nees"])
        img = images[(m, k)]
        rho = img["rho_state"]
        n = int(s.sum())
        neff = n_effective(n, rho)
        lo, hi = chi2_band_sum(6.0 * neff)
        rho_nu = _value(img.get("common_share_innov"))
        has = (c["method"] == m) & (c["frame"] == k) & np.isfinite(c["nis"]) & (c["dof"] > 0)
        dof_total = float(c["dof"][has].sum())
        dof_eff = dof_total / (1.0 + (n - 1) * rho_nu**2) if math.isfinite(rho_nu) else dof_total
        nlo, nhi = chi2_band_sum(dof_eff)
        a, b = r["anees"] / 6.0, r["anis_per_dof"]
        out.append({"method": m, "frame": int(k), "t_s": r["t_s"], "n_runs": n, "anees_over_6": a,
                    "anees_lo": r["anees_lo"] / 6.0, "anees_hi": r["anees_hi"] / 6.0,
                    "anees_inside": r["anees_inside"], "rho_state": rho, "n_eff": neff,
                    "anees_lo_eff": lo, "anees_hi_eff": hi,
                    "anees_inside_eff": bool(lo <= a <= hi) if math.isfinite(lo) else None,
                    "anis_per_dof": b, "anis_lo": r["anis_lo"], "anis_hi": r["anis_hi"],
                    "anis_inside": r["anis_inside"], "rho_innov": rho_nu, "nis_dof_eff": dof_eff,
                    "anis_lo_eff": nlo, "anis_hi_eff": nhi,
                    "anis_inside_eff": bool(nlo <= b <= nhi) if math.isfinite(nlo) and math.isfinite(b) else None,
                    "common_share_err_s": _value(img.get("common_share_err_s")),
                    "common_share_err_l": _value(img.get("common_share_err_l"))})
    return out


def _value(v) -> float:
    return math.nan if v is None else float(v)


def band_summary(rows: list[dict]) -> list[dict]:
    """Per method: share of images inside the plain and the effective bands, mean ρ, ρ_ν and landmark shares."""
    out = []
    for m in sorted({r["method"] for r in rows}):
        rr = [r for r in rows if r["method"] == m]

        def frac(key, rr=rr):
            v = [bool(r[key]) for r in rr if r[key] is not None]
            return float(np.mean(v)) if v else math.nan

        def mean(key, rr=rr):
            v = np.array([r[key] for r in rr], float)
            return float(np.nanmean(v)) if np.isfinite(v).any() else math.nan

        out.append({"method": m, "images": len(rr), "nees_inside_plain": frac("anees_inside"),
                    "nees_inside_eff": frac("anees_inside_eff"), "nis_inside_plain": frac("anis_inside"),
                    "nis_inside_eff": frac("anis_inside_eff"), "rho_state_mean": mean("rho_state"),
                    "rho_state_max": float(np.nanmax([r["rho_state"] for r in rr])),
                    "n_eff_min": float(np.nanmin([r["n_eff"] for r in rr])), "rho_innov_mean": mean("rho_innov"),
                    "common_share_err_s_mean": mean("common_share_err_s"),
                    "common_share_err_l_mean": mean("common_share_err_l")})
    return out


def similarity_pattern(truth_s, truth_l, err_s, err_l) -> dict | None:
    """The similarity transform common to the landmark errors of one image (kept landmarks of the runs that kept
    track), fitted by least squares, e = a·(x, y) + b·(−y, x) + (t_s, t_l) with (x, y) the true pixel minus the
    landmarks' centroid: ``scale`` a (a range error of −a·range to first order for a nadir view), ``rotation`` b
    (rad) and the shift (px); None below 3 landmarks. An error of this form shared by every landmark of an image
    cannot average out over landmarks or runs."""
    k = np.isfinite(err_s) & np.isfinite(err_l)
    n = int(k.sum())
    if n < 3:
        return None
    x, y = truth_s[k] - np.mean(truth_s[k]), truth_l[k] - np.mean(truth_l[k])
    A = np.zeros((2 * n, 4))
    A[:n, 0], A[n:, 0], A[:n, 1], A[n:, 1] = x, y, -y, x
    A[:n, 2], A[n:, 3] = 1.0, 1.0
    sol, *_ = np.linalg.lstsq(A, np.r_[err_s[k], err_l[k]], rcond=None)
    return {"n_landmarks": n, "scale": float(sol[0]), "rotation_rad": float(sol[1]), "shift_s_px": float(sol[2]),
            "shift_l_px": float(sol[3]), "radius_max_px": float(np.max(np.hypot(x, y)))}
