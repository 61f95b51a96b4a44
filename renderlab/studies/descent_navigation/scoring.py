"""Scores of the descent campaign from its tables alone: consistency per method and image, per-method summary.

Consistency is scored over the runs that never lost track (a run that lost track is counted in ``track_lost_runs``
and its NEES/NIS reported apart as ``*_all``: a diverged run's NEES, 10⁴–10⁵, would otherwise be the average).
Per method and image time (runs are independent, so the run average of a χ² variable has the band of χ²(N·dof)/N):
ANEES = mean over runs of NEES (6 dof), band χ²₀.₀₂₅,₀.₉₇₅(6N)/N; ANIS = Σ NIS / Σ dof over the runs (dof varies
with the landmarks kept), band χ²(Σ dof)/Σ dof; position RMS error and the RMS of the filter's 3σ. Per method:
the time-mean ANEES / 6 and ANIS / dof (each with a 95 % percentile bootstrap interval that resamples whole runs,
so the correlation of a run's images is kept), the share of image times inside the bands, the error at the last
image ("touchdown proxy", 50 m), track loss, the landmark errors of the kept landmarks (bias with a run-cluster
bootstrap interval), and the gate's and the method's rejections.
"""

from __future__ import annotations

import math

import numpy as np

from renderlab.stats.bootstrap import cluster_bootstrap
from renderlab.stats.consistency import chi2_band_sum, columns, tracked

POS = ("err_e_m", "err_n_m", "err_u_m")
VEL = ("err_ve_mps", "err_vn_mps", "err_vu_mps")


def timeseries(ftab) -> list[dict]:
    """One row per method and image (the prior excluded): consistency and error statistics over the runs that kept
    track (module docstring); ``track_lost_runs`` counts the others."""
    all_lost = columns(ftab, ("method", "frame", "track_lost"))
    ftab = tracked(ftab)
    c = columns(ftab, ("method", "frame", "t_s", "nees", "nis", "dof", "n_kept", "track_lost", *POS, *VEL,
                       "sig_e_m", "sig_n_m", "sig_u_m"))
    out = []
    for m in sorted(set(c["method"].tolist())):
        for k in sorted(set(c["frame"][c["method"] == m].tolist())):
            s = (c["method"] == m) & (c["frame"] == k)
            ok = s & np.isfinite(c["nees"])
            n = int(ok.sum())
            anees = float(np.mean(c["nees"][ok])) if n else math.nan
            lo, hi = chi2_band_sum(6.0 * n)
            has = s & np.isfinite(c["nis"]) & (c["dof"] > 0)
            dof = float(c["dof"][has].sum())
            anis = float(c["nis"][has].sum() / dof) if dof else math.nan
            nlo, nhi = chi2_band_sum(dof)
            pos = np.stack([c[a][ok] for a in POS], 1)
            vel = np.stack([c[a][ok] for a in VEL], 1)
            sig = np.stack([c[a][ok] for a in ("sig_e_m", "sig_n_m", "sig_u_m")], 1)
            out.append({"method": m, "frame": int(k), "t_s": float(np.mean(c["t_s"][s])), "n_runs": n,
                        "anees": anees, "anees_lo": lo * 6, "anees_hi": hi * 6,
                        "anees_inside": bool(lo * 6 <= anees <= hi * 6) if n and k >= 0 else None,
                        "anis_per_dof": anis, "anis_lo": nlo, "anis_hi": nhi,
                        "anis_inside": bool(nlo <= anis <= nhi) if dof else None,
                        "pos_rms_m": float(np.sqrt(np.mean(np.sum(pos**2, 1)))) if n else math.nan,
                        "vel_rms_mps": float(np.sqrt(np.mean(np.sum(vel**2, 1)))) if n else math.nan,
                        **{f"pos3sig_{a}_m": float(3 * np.sqrt(np.mean(sig[:, j] ** 2))) if n else math.nan
                           for j, a in enumerate("enu")},
                        "mean_kept": float(np.mean(c["n_kept"][s])),
                        "track_lost_runs": int(all_lost["track_lost"][(all_lost["method"] == m)
                                                                     & (all_lost["frame"] == k)].sum())})
    return out


def _run_bootstrap(per_run: np.ndarray, seed: int = 0, n_boot: int = 2000) -> tuple[float, float]:
    """95 % percentile interval of the mean of per-run values (runs resampled whole)."""
    v = per_run[np.isfinite(per_run)]
    if v.size < 2:
        return math.nan, math.nan
    rng = np.random.default_rng(seed)
    means = v[rng.integers(0, v.size, (n_boot, v.size))].mean(1)
    return float(np.percentile(means, 2.5)), float(np.percentile(means, 97.5))


def _per_run(c, m, value, reduce) -> np.ndarray:
    runs = sorted(set(c["run"][c["method"] == m].tolist()))
    return np.array([reduce(value, (c["method"] == m) & (c["run"] == r)) for r in runs], float)


def _consistency(c, m) -> tuple[np.ndarray, np.ndarray]:
    """Per-run time-mean NEES/6 and NIS/dof of method m over its images."""
    img = (c["method"] == m) & (c["frame"] >= 0)
    nees_run = _per_run(c, m, None, lambda _, s: np.nanmean(c["nees"][s & img]) / 6.0)
    nis_run = _per_run(c, m, None, lambda _, s: np.nansum(c["nis"][s & img]) / max(c["dof"][s & img].sum(), 1))
    return nees_run, nis_run


def method_summary(ftab, ltab, ts_rows) -> list[dict]:
    """One row per method (module docstring): consistency and landmark statistics over the runs that kept track
    (``*_all``: every run), errors at the last image over every run."""
    keep = columns(tracked(ftab), ("run", "method", "frame", "nees", "nis", "dof"))
    c = columns(ftab, ("run", "method", "frame", "nees", "nis", "dof", "track_lost", "n_gated", "n_flagged",
                       "n_results", "n_kept", *POS, *VEL))
    lc = columns(tracked(ltab) if ltab is not None and "track_lost" in ltab.column_names else ltab,
                 ("run", "method", "err_s", "err_l", "kept", "has_result")) if ltab is not None else None
    if lc is not None:                      # landmark statistics over the runs that kept track, as the consistency
        ok = {(m, r) for m, r in zip(keep["method"].tolist(), keep["run"].tolist())}
        sel = np.array([(m, r) in ok for m, r in zip(lc["method"].tolist(), lc["run"].tolist())], bool)
        lc = {k: v[sel] for k, v in lc.items()}
    out = []
    for m in sorted(set(c["method"].tolist())):
        img = (c["method"] == m) & (c["frame"] >= 0)
        last = img & (c["frame"] == c["frame"][img].max())
        nees_run, nis_run = _consistency(keep, m)
        nees_all, nis_all = _consistency(c, m)
        td = np.sqrt(sum(c[a][last] ** 2 for a in POS))
        tdv = np.sqrt(sum(c[a][last] ** 2 for a in VEL))
        rows = [r for r in ts_rows if r["method"] == m and r["frame"] >= 0]
        row = {"method": m, "n_runs": int(last.sum()), "n_tracked_runs": int(len(nees_run)),
               "anees_over_6": float(np.nanmean(nees_run)),
               "anees_over_6_lo": _run_bootstrap(nees_run)[0], "anees_over_6_hi": _run_bootstrap(nees_run)[1],
               "anees_inside_frac": float(np.mean([bool(r["anees_inside"]) for r in rows])),
               "anis_per_dof": float(np.nanmean(nis_run)), "anis_per_dof_lo": _run_bootstrap(nis_run)[0],
               "anis_per_dof_hi": _run_bootstrap(nis_run)[1],
               "anis_inside_frac": float(np.mean([bool(r["anis_inside"]) for r in rows if r["anis_inside"] is not None]
                                                 or [False])),
               "anees_over_6_all": float(np.nanmean(nees_all)), "anis_per_dof_all": float(np.nanmean(nis_all)),
               "touchdown_pos_err_median_m": float(np.nanmedian(td)),
               "touchdown_pos_err_p95_m": float(np.nanpercentile(td, 95)),
               "touchdown_pos_err_rms_m": float(np.sqrt(np.nanmean(td**2))),
               "touchdown_vel_err_rms_mps": float(np.sqrt(np.nanmean(tdv**2))),
               "touchdown_pos_3sig_rms_m": float(math.sqrt(sum(rows[-1][f"pos3sig_{a}_m"] ** 2 for a in "enu"))),
               "track_lost_runs": int(c["track_lost"][last].sum()),
               "gated_frac": float(c["n_gated"][img].sum() / max(c["n_results"][img].sum(), 1)),
               "flagged_frac": float(c["n_flagged"][img].sum() / max(c["n_results"][img].sum(), 1)),
               "kept_per_image": float(np.mean(c["n_kept"][img]))}
        if lc is not None:
            k = (lc["method"] == m) & lc["kept"]
            for ax in ("s", "l"):
                e = lc[f"err_{ax}"][k]
                iv = cluster_bootstrap(e, lc["run"][k], "mean", cluster_name="runs")
                row.update({f"kept_bias_{ax}_px": iv.estimate, f"kept_bias_{ax}_px_lo": iv.lo,
                            f"kept_bias_{ax}_px_hi": iv.hi,
                            f"kept_std_{ax}_px": float(np.std(e, ddof=1)) if e.size > 1 else math.nan})
        out.append(row)
    return out
