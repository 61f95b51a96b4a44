"""Scores of the GN&C descent campaign from its two tables alone (``gnc_images``, ``gnc_runs``): touchdown miss and
its 3σ (the runs' and the filter's claim), Δv, propellant, ANEES/ANIS with χ² bands over all runs and over the runs
that kept track, track loss. Every interval is a 95 % percentile bootstrap over whole runs
(:func:`renderlab.stats.bootstrap.cluster_bootstrap`, seed 0): runs are independent, a run's images are not.
Definitions: ``docs/descent_gnc.md``.
"""

from __future__ import annotations

import math

import numpy as np

from renderlab.stats.bootstrap import cluster_bootstrap
from renderlab.stats.consistency import chi2_band_sum, columns
from renderlab.studies.descent_gnc.tables import MISSES

#: columns read by the report, the published-tier test (t_end_s), the README (widen, search_px), bench_descent_gnc (t_*_ms)
PUBLISHED = {"gnc_images": ("run", "method", "mode", "image", "status", "nis", "nis_dof", "nees", "t_s", "altitude_m",
                            "widen", "search_px", "err_e_m", "err_n_m", "err_u_m", "sig_e_m", "sig_n_m", "ctl_e_m",
                            "ctl_n_m", "ctl_u_m"),
             "gnc_runs": ("run", "method", "mode", "touchdown", "t_end_s", "track_lost", "td_e_m", "td_n_m", "td_ve_mps",
                          "td_vn_mps", "td_vu_mps", "nav_e_m", "nav_n_m", "sig_e_m", "sig_n_m", "rho_en", "sig_ve_mps",
                          "sig_vn_mps", "rho_ven", "delta_v_mps", "propellant_kg", "loss_cause", "loss_t_s",
                          "loss_altitude_m", "reacquired", "init_pos_err_max_sigma", "init_vel_err_max_sigma",
                          "t_render_ms", "t_measure_ms", "t_filter_ms", "t_flight_ms")}


def publish_tables(tables: dict) -> dict:
    """The published tables (``Study.publish_tables``): the :data:`PUBLISHED` columns, full precision."""
    from renderlab.campaign.compact import keep_columns

    return keep_columns(tables, PUBLISHED)


def cols(table) -> dict:
    """Every column of a pyarrow table as a numpy array (text columns as object arrays)."""
    return columns(table, table.column_names)


def sigma3_max(cov: np.ndarray) -> float:
    """3 √λ_max of a 2×2 covariance."""
    return float(3.0 * math.sqrt(max(float(np.linalg.eigvalsh(cov)[-1]), 0.0)))


def claimed_cov(r: dict, sel: np.ndarray, pre: str, unit: str) -> np.ndarray:
    """RMS over the selected runs of the filter's horizontal covariance at contact."""
    se, sn, rho = r[f"sig_{pre}e_{unit}"][sel], r[f"sig_{pre}n_{unit}"][sel], r[f"rho_{pre}en"][sel]
    return np.array([[np.mean(se**2), np.mean(rho * se * sn)], [np.mean(rho * se * sn), np.mean(sn**2)]])


def _ci(values, runs, stat="mean") -> tuple[float, float, float]:
    iv = cluster_bootstrap(values, runs, stat)
    return float(iv.estimate), float(iv.lo), float(iv.hi)


def _consistency(im: dict, sel: np.ndarray, prefix: str) -> dict:
    """ANEES/6 and ANIS/dof of the selected image rows with run-bootstrap intervals (module docstring)."""
    keys = [f"{prefix}{k}{s}" for k in ("anees_over_6", "anis_per_dof") for s in ("", "_lo", "_hi")]
    out = dict.fromkeys(keys, math.nan)
    if not sel.any():
        return out
    runs = im["run"][sel]
    ur = np.unique(runs)
    out.update(zip(keys[:3], _ci(np.array([np.mean(im["nees"][sel][runs == u]) / 6.0 for u in ur]), ur)))
    has = sel & (im["status"] == "ok") & (im["nis_dof"] > 0)
    nis, dof, rr = im["nis"][has], im["nis_dof"][has].astype(float), im["run"][has]

    def ratio(idx):
        return float(nis[idx].sum() / dof[idx].sum()) if dof[idx].sum() > 0 else math.nan

    if has.any():
        iv = cluster_bootstrap(np.arange(len(nis)), rr, lambda ix: ratio(ix.astype(int)))
        out.update(zip(keys[3:], (ratio(np.arange(len(nis))), float(iv.lo), float(iv.hi))))
    return out


def timeseries(im: dict, lost: set) -> list[dict]:
    """One row per method, mode, image index and run set (``all`` / ``kept``): errors, control error, χ² bands."""
    out = []
    for m in sorted(set(im["method"])):
        for mode in sorted(set(im["mode"])):
            base = (im["method"] == m) & (im["mode"] == mode)
            keep = np.array([(m, mode, int(r)) not in lost for r in im["run"]])
            for subset, mask in (("all", base), ("kept", base & keep)):
                for k in sorted(set(im["image"][mask].tolist())):
                    s = mask & (im["image"] == k)
                    n = int(s.sum())
                    lo, hi = chi2_band_sum(6.0 * n)
                    anees = float(np.mean(im["nees"][s]))
                    has = s & (im["status"] == "ok") & (im["nis_dof"] > 0)
                    dof = float(im["nis_dof"][has].sum())
                    anis = float(im["nis"][has].sum() / dof) if dof else math.nan
                    nlo, nhi = chi2_band_sum(dof)
                    h_est = np.hypot(im["err_e_m"][s], im["err_n_m"][s])
                    h_ctl = np.hypot(im["ctl_e_m"][s], im["ctl_n_m"][s])
                    sig_h = np.sqrt(im["sig_e_m"][s] ** 2 + im["sig_n_m"][s] ** 2)
                    out.append({"method": m, "mode": mode, "runs": subset, "image": int(k),
                                "t_s": float(np.mean(im["t_s"][s])), "altitude_m": float(np.mean(im["altitude_m"][s])),
                                "n_runs": n, "est_h_rms_m": float(np.sqrt(np.mean(h_est**2))),
                                "est_u_rms_m": float(np.sqrt(np.mean(im["err_u_m"][s] ** 2))),
                                "ctl_h_rms_m": float(np.sqrt(np.mean(h_ctl**2))),
                                "ctl_u_rms_m": float(np.sqrt(np.mean(im["ctl_u_m"][s] ** 2))),
                                "sig3_h_rms_m": float(3 * np.sqrt(np.mean(sig_h**2))),
                                "anees_over_6": anees / 6.0, "anees_lo": lo, "anees_hi": hi,
                                "anees_pass": bool(lo <= anees / 6.0 <= hi),
                                "anis_per_dof": anis, "anis_lo": nlo, "anis_hi": nhi,
                                "anis_pass": bool(nlo <= anis <= nhi) if dof else None,
                                "misses": int(np.isin(im["status"][s], MISSES).sum())})
    return out


def summary(im: dict, r: dict, ts_rows: list[dict]) -> list[dict]:
    """One row per method and mode (module docstring)."""
    out = []
    lost = lost_keys(r)
    for m in sorted(set(r["method"])):
        for mode in sorted(set(r["mode"])):
            sel = (r["method"] == m) & (r["mode"] == mode)
            if not sel.any():
                continue
            runs = r["run"][sel]
            h = np.hypot(r["td_e_m"][sel], r["td_n_m"][sel])
            vh = np.hypot(r["td_ve_mps"][sel], r["td_vn_mps"][sel])
            row = {"method": m, "mode": mode, "n_runs": int(sel.sum()), "touchdowns": int(r["touchdown"][sel].sum()),
                   "track_lost_runs": int(r["track_lost"][sel].sum())}
            for key, vals, stat in (("td_h_median_m", h, "median"), ("td_vu_err_mean_mps", r["td_vu_mps"][sel], "mean"),
                                    ("td_vh_median_mps", vh, "median"), ("delta_v_mean_mps", r["delta_v_mps"][sel], "mean"),
                                    ("propellant_mean_kg", r["propellant_kg"][sel], "mean")):
                row[key], row[key + "_lo"], row[key + "_hi"] = _ci(vals, runs, stat)
            row["td_h_p95_m"] = float(np.percentile(h, 95))
            pos = np.stack([r["td_e_m"][sel], r["td_n_m"][sel]])
            vel = np.stack([r["td_ve_mps"][sel], r["td_vn_mps"][sel]])
            row["td_h_3sig_runs_m"] = sigma3_max(np.cov(pos)) if sel.sum() > 2 else math.nan
            row["td_h_3sig_claimed_m"] = sigma3_max(claimed_cov(r, sel, "", "m"))
            row["td_vh_3sig_runs_mps"] = sigma3_max(np.cov(vel)) if sel.sum() > 2 else math.nan
            row["td_vh_3sig_claimed_mps"] = sigma3_max(claimed_cov(r, sel, "v", "mps"))
            row["nav_h_median_m"] = float(np.median(np.hypot(r["nav_e_m"][sel], r["nav_n_m"][sel])))
            isel = (im["method"] == m) & (im["mode"] == mode)
            keep = np.array([(m, mode, int(x)) not in lost for x in im["run"]])
            row.update({**_consistency(im, isel, ""), **_consistency(im, isel & keep, "kept_")})
            tsr = [t for t in ts_rows if t["method"] == m and t["mode"] == mode and t["runs"] == "all"]
            row["anees_times_in_band"] = float(np.mean([t["anees_pass"] for t in tsr])) if tsr else math.nan
            nis_t = [t["anis_pass"] for t in tsr if t["anis_pass"] is not None]
            row["anis_times_in_band"] = float(np.mean(nis_t)) if nis_t else math.nan
            row["anees_pass"] = bool(row["anees_over_6_lo"] <= 1.0 <= row["anees_over_6_hi"])
            row["anis_pass"] = bool(row["anis_per_dof_lo"] <= 1.0 <= row["anis_per_dof_hi"])
            out.append(row)
    return out


def lost_keys(r: dict) -> set:
    """(method, mode, run) of the flights that lost track."""
    return {(m, mo, int(x)) for m, mo, x, lo in zip(r["method"], r["mode"], r["run"], r["track_lost"]) if lo}


def track_loss_rows(r: dict) -> list[dict]:
    """One row per flight that lost track: when, where, why, and the initial error it drew."""
    out = [{"method": str(r["method"][i]), "mode": str(r["mode"][i]), "run": int(r["run"][i]),
            "cause": str(r["loss_cause"][i]), "t_s": float(r["loss_t_s"][i]),
            "altitude_m": float(r["loss_altitude_m"][i]), "reacquired": bool(r["reacquired"][i]),
            "init_vel_err_max_sigma": float(r["init_vel_err_max_sigma"][i]),
            "init_pos_err_max_sigma": float(r["init_pos_err_max_sigma"][i]),
            "td_h_m": float(np.hypot(r["td_e_m"][i], r["td_n_m"][i]))} for i in np.flatnonzero(r["track_lost"])]
    return sorted(out, key=lambda x: (x["method"], x["mode"], x["run"]))
