"""Scores of the GN&C descent campaign from its two tables alone (``gnc_images``, ``gnc_runs``).

Runs are independent; the images of a run are not. Every interval is a 95 % percentile bootstrap that resamples
whole runs (:func:`renderlab.stats.bootstrap.cluster_bootstrap`, cluster = run, seed 0). Per method and mode:

* **touchdown**: horizontal miss |(e, n)| of the true contact point from the target, median and 95th percentile;
  vertical and horizontal speed error; the runs' own 3σ (3 √λ_max of the sample covariance of (e, n)) beside the
  3σ the filter claims at contact (3 √λ_max of its horizontal covariance, RMS over runs);
* **Δv and propellant** (L1 over the thruster axes; propellant = impulse / (I_sp g0)), mean;
* **consistency**: ANEES/6 = the mean over runs of each run's mean NEES/6 over its images; ANIS/dof = Σ NIS / Σ dof
  over the images the filter kept; PASS when 1 lies inside the run-bootstrap interval; per image index the run
  average against its χ² band (ANEES: χ²(6N)/(6N), N runs; ANIS: χ²(Σ dof)/Σ dof, two-sided 95 %), and the share
  of image times inside; each over **all runs** and over the **runs that kept track**;
* **track loss**: runs with a track loss (``track_loss_images`` consecutive missed images), by cause.
"""

from __future__ import annotations

import math

import numpy as np

from renderlab.stats.bootstrap import cluster_bootstrap
from renderlab.stats.consistency import chi2_band_sum


def cols(table) -> dict:
    """Every column of a pyarrow table as a numpy array (dictionary columns as strings)."""
    out = {}
    for n in table.column_names:
        c = table.column(n)
        out[n] = np.asarray(c.to_pylist() if "dictionary" in str(c.type) or c.type == "string" else
                            c.to_numpy(zero_copy_only=False))
    return out


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
    out = {}
    runs = im["run"][sel]
    if not sel.any():
        return {f"{prefix}{k}": math.nan for k in ("anees_over_6", "anees_over_6_lo", "anees_over_6_hi",
                                                  "anis_per_dof", "anis_per_dof_lo", "anis_per_dof_hi")}
    ur = np.unique(runs)
    per_run = np.array([np.mean(im["nees"][sel][runs == u]) / 6.0 for u in ur])
    out[f"{prefix}anees_over_6"], out[f"{prefix}anees_over_6_lo"], out[f"{prefix}anees_over_6_hi"] = \
        _ci(per_run, ur)
    has = sel & (im["status"] == "ok") & (im["nis_dof"] > 0)
    nis, dof, rr = im["nis"][has], im["nis_dof"][has].astype(float), im["run"][has]

    def ratio(idx):
        return float(nis[idx].sum() / dof[idx].sum()) if dof[idx].sum() > 0 else math.nan

    if has.any():
        iv = cluster_bootstrap(np.arange(len(nis)), rr, lambda ix: ratio(ix.astype(int)))
        out[f"{prefix}anis_per_dof"], out[f"{prefix}anis_per_dof_lo"], out[f"{prefix}anis_per_dof_hi"] = \
            ratio(np.arange(len(nis))), float(iv.lo), float(iv.hi)
    else:
        out.update({f"{prefix}anis_per_dof{s}": math.nan for s in ("", "_lo", "_hi")})
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
                                "misses": int(np.isin(im["status"][s], ("no_match", "all_gated", "nis_rejected",
                                                                       "diverged")).sum())})
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
            for key, vals, stat in (("td_h_median_m", h, "median"), ("td_vu_err_mean_mps", r["td_vu_mps"][sel],
                                                                      "mean"),
                                    ("td_vh_median_mps", vh, "median"), ("delta_v_mean_mps", r["delta_v_mps"][sel],
                                                                         "mean"),
                                    ("propellant_mean_kg", r["propellant_kg"][sel], "mean")):
                row[key], row[key + "_lo"], row[key + "_hi"] = _ci(vals, runs, stat)
            row["td_h_p95_m"] = float(np.percentile(h, 95))
            pos = np.stack([r["td_e_m"][sel], r["td_n_m"][sel]])
            vel = np.stack([r["td_ve_mps"][sel], r["td_vn_mps"][sel]])
            row["td_h_3sig_runs_m"] = sigma3_max(np.cov(pos)) if sel.sum() > 2 else math.nan
            row["td_h_3sig_claimed_m"] = sigma3_max(claimed_cov(r, sel, "", "m"))
            row["td_vh_3sig_runs_mps"] = sigma3_max(np.cov(vel)) if sel.sum() > 2 else math.nan
            row["td_vh_3sig_claimed_mps"] = sigma3_max(claimed_cov(r, sel, "v", "mps"))
            nav = np.hypot(r["nav_e_m"][sel], r["nav_n_m"][sel])
            row["nav_h_median_m"] = float(np.median(nav))
            isel = (im["method"] == m) & (im["mode"] == mode)
            keep = np.array([(m, mode, int(x)) not in lost for x in im["run"]])
            row.update(_consistency(im, isel, ""))
            row.update(_consistency(im, isel & keep, "kept_"))
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
    out = []
    for i in np.flatnonzero(r["track_lost"]):
        out.append({"method": str(r["method"][i]), "mode": str(r["mode"][i]), "run": int(r["run"][i]),
                    "cause": str(r["loss_cause"][i]), "t_s": float(r["loss_t_s"][i]),
                    "altitude_m": float(r["loss_altitude_m"][i]), "reacquired": bool(r["reacquired"][i]),
                    "init_vel_err_max_sigma": float(r["init_vel_err_max_sigma"][i]),
                    "init_pos_err_max_sigma": float(r["init_pos_err_max_sigma"][i]),
                    "td_h_m": float(np.hypot(r["td_e_m"][i], r["td_n_m"][i]))})
    return sorted(out, key=lambda x: (x["method"], x["mode"], x["run"]))
