"""Scores of the descent campaign from its tables alone: consistency per method and image over the runs that kept
track, per-method summary with run-bootstrap intervals (docs/descent_navigation.md, "Scores")."""

from __future__ import annotations

import math

import numpy as np

from renderlab.stats.bootstrap import cluster_bootstrap, cluster_mean_bootstrap
from renderlab.stats.consistency import chi2_band_sum, columns, tracked

POS = ("err_e_m", "err_n_m", "err_u_m")
VEL = ("err_ve_mps", "err_vn_mps", "err_vu_mps")


def timeseries(ftab, images: dict) -> list[dict]:
    """One row per method and image (the prior excluded): consistency and error statistics over the runs that kept
    track (module docstring); ``track_lost_runs`` counts the others. ``images``: ``{(method, frame): row}`` of the
    published ``descent_images`` table (the mean squared 1σ ``sig2_e/n/u``)."""
    all_lost = columns(ftab, ("method", "frame", "track_lost"))
    ftab = tracked(ftab)
    c = columns(ftab, ("method", "frame", "t_s", "nees", "nis", "dof", "n_kept", "track_lost", *POS, *VEL))
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
            img = images[(m, int(k))]
            out.append({"method": m, "frame": int(k), "t_s": float(np.mean(c["t_s"][s])), "n_runs": n,
                        "anees": anees, "anees_lo": lo * 6, "anees_hi": hi * 6,
                        "anees_inside": bool(lo * 6 <= anees <= hi * 6) if n and k >= 0 else None,
                        "anis_per_dof": anis, "anis_lo": nlo, "anis_hi": nhi,
                        "anis_inside": bool(nlo <= anis <= nhi) if dof else None,
                        "pos_rms_m": float(np.sqrt(np.mean(np.sum(pos**2, 1)))) if n else math.nan,
                        "vel_rms_mps": float(np.sqrt(np.mean(np.sum(vel**2, 1)))) if n else math.nan,
                        **{f"pos3sig_{a}_m": float(3 * np.sqrt(img[f"sig2_{a}"])) if n else math.nan for a in "enu"},
                        "mean_kept": float(np.mean(c["n_kept"][s])),
                        "track_lost_runs": int(all_lost["track_lost"][(all_lost["method"] == m)
                                                                     & (all_lost["frame"] == k)].sum())})
    return out


def _run_ci(per_run: np.ndarray) -> tuple[float, float]:
    """95 % percentile interval of the mean of per-run values (runs resampled whole, seed 0, 2000 resamples)."""
    v = per_run[np.isfinite(per_run)]
    iv = cluster_bootstrap(v, np.arange(v.size), "mean", cluster_name="runs")
    return iv.lo, iv.hi


def _per_run(c, m, value, reduce) -> np.ndarray:
    runs = sorted(set(c["run"][c["method"] == m].tolist()))
    return np.array([reduce(value, (c["method"] == m) & (c["run"] == r)) for r in runs], float)


def _consistency(c, m) -> tuple[np.ndarray, np.ndarray]:
    """Per-run time-mean NEES/6 and NIS/dof of method m over its images."""
    img = (c["method"] == m) & (c["frame"] >= 0)
    nees_run = _per_run(c, m, None, lambda _, s: np.nanmean(c["nees"][s & img]) / 6.0)
    nis_run = _per_run(c, m, None, lambda _, s: np.nansum(c["nis"][s & img]) / max(c["dof"][s & img].sum(), 1))
    return nees_run, nis_run


def method_summary(ftab, runs, ts_rows) -> list[dict]:
    """One row per method (module docstring): consistency and landmark statistics over the runs that kept track
    (``*_all``: every run), errors at the last image over every run; ``runs``: the published
    ``descent_landmark_runs`` table (per method and run, sums of the kept landmarks' errors) or None."""
    keep = columns(tracked(ftab), ("run", "method", "frame", "nees", "nis", "dof"))
    c = columns(ftab, ("run", "method", "frame", "nees", "nis", "dof", "track_lost", "n_gated", "n_flagged",
                       "n_results", "n_kept", *POS, *VEL))
    lc = columns(runs, ("method", "n_rows", "n_s", "sum_s", "sumsq_s", "n_l", "sum_l", "sumsq_l")) \
        if runs is not None else None
    out = []
    for m in sorted(set(c["method"].tolist())):
        img = (c["method"] == m) & (c["frame"] >= 0)
        last = img & (c["frame"] == c["frame"][img].max())
        nees_run, nis_run = _consistency(keep, m)
        nees_all, nis_all = _consistency(c, m)
        td = np.sqrt(sum(c[a][last] ** 2 for a in POS))
        tdv = np.sqrt(sum(c[a][last] ** 2 for a in VEL))
        rows = [r for r in ts_rows if r["method"] == m and r["frame"] >= 0]
        (a_lo, a_hi), (n_lo, n_hi) = _run_ci(nees_run), _run_ci(nis_run)
        row = {"method": m, "n_runs": int(last.sum()), "n_tracked_runs": int(len(nees_run)),
               "anees_over_6": float(np.nanmean(nees_run)), "anees_over_6_lo": a_lo, "anees_over_6_hi": a_hi,
               "anees_inside_frac": float(np.mean([bool(r["anees_inside"]) for r in rows])),
               "anis_per_dof": float(np.nanmean(nis_run)), "anis_per_dof_lo": n_lo, "anis_per_dof_hi": n_hi,
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
            k = lc["method"] == m
            for ax in ("s", "l"):
                iv = cluster_mean_bootstrap(lc[f"n_{ax}"][k], lc[f"sum_{ax}"][k], cluster_name="runs")
                n, s1, s2 = lc["n_rows"][k].sum(), lc[f"sum_{ax}"][k].sum(), lc[f"sumsq_{ax}"][k].sum()
                row.update({f"kept_bias_{ax}_px": iv.estimate, f"kept_bias_{ax}_px_lo": iv.lo,
                            f"kept_bias_{ax}_px_hi": iv.hi,
                            f"kept_std_{ax}_px": float(math.sqrt((s2 - s1 * s1 / n) / (n - 1))) if n > 1
                            else math.nan})
        out.append(row)
    return out
