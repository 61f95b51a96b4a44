"""Scoring of the coastline-EKF Monte Carlo: Monte Carlo vs filter σ, ANEES/ANIS with 99 % χ² bands (Bar-Shalom,
Li & Kirubarajan §5.4), the posterior Cramér–Rao bound (Tichavský et al. 1998, doi:10.1109/78.668800) and the
steady-state numbers of Table 1 (Straub & Christian). The theory: docs/coastline_ekf.md.
"""

from __future__ import annotations

import numpy as np

from estimators.coastline.dynamics import propagate_state_stm, white_acceleration_qd
from estimators.coastline.los import los_jacobian_position, los_predict, skew_batch
from renderlab.dynamics.orbits import ric_axes
from renderlab.stats.consistency import chi2_band_mean, chi2_sum_test

__all__ = ["AXES", "chi2_band", "per_time_summary", "pcrb_ric_sigma", "steady_state", "nis_total_test",
           "nis_band_test"]
chi2_band, nis_band_test = chi2_band_mean, chi2_sum_test  # the study's names (99 % bands)

AXES = [("r", "m"), ("i", "m"), ("c", "m"), ("vr", "mps"), ("vi", "mps"), ("vc", "mps")]
ERR = [f"err_{a}_{u}" for a, u in AXES]
SIG = [f"sig_{a}_{u}" for a, u in AXES]


def _columns(table) -> tuple[dict[str, np.ndarray], int, int]:
    runs = table["run"].to_numpy()
    N = len(np.unique(runs))
    K = len(runs) // N
    order = np.lexsort((table["t_s"].to_numpy(), runs))
    cols = {c: table[c].to_numpy()[order].reshape(N, K) for c in table.column_names}
    return cols, N, K


def per_time_summary(table, pcrb_sigma: np.ndarray | None = None, p: float = 0.99):
    """One row per time of the filter table (all runs on the same times): MC mean and RMS error, RMS filter σ, PCRB σ
    (``pcrb_sigma`` (K, 6) of :func:`pcrb_ric_sigma`, optional), ANEES/ANIS and their χ² bands."""
    import pyarrow as pa

    c, N, K = _columns(table)
    # mean LOS count over runs (the image mode's can differ per run; the band stays exact: docs/coastline_ekf.md)
    out = {"t_s": c["t_s"][0], "n_meas": c["n_meas"].astype(np.float64).mean(axis=0)}
    for e, s in zip(ERR, SIG):
        out[e.replace("err_", "mc_mean_")] = c[e].mean(axis=0)
        out[e.replace("err_", "mc_rms_")] = np.sqrt(np.mean(c[e] ** 2, axis=0))
        out[s.replace("sig_", "filter_sig_")] = np.sqrt(np.mean(c[s] ** 2, axis=0))
        if pcrb_sigma is not None:
            out[s.replace("sig_", "pcrb_sig_")] = pcrb_sigma[:, SIG.index(s)]
    out["anees"] = c["nees"].mean(axis=0)
    out["anees_lo"], out["anees_hi"] = chi2_band(np.full(K, 6.0), N, p)
    with np.errstate(invalid="ignore"):
        out["anis"] = np.where(out["n_meas"] > 0, np.nanmean(np.where(np.isnan(c["nis"]), 0.0, c["nis"]), axis=0),
                               np.nan)
    out["anis_lo"], out["anis_hi"] = chi2_band(2.0 * out["n_meas"], N, p)
    out["n_runs"] = np.full(K, N, dtype=np.int32)
    return pa.table(out)


def nis_total_test(table, p: float = 0.99) -> dict:
    """All NIS of all runs and images summed against χ²(N Σ 2m_k): value, band, inside."""
    c, N, K = _columns(table)
    return nis_band_test(float(np.nansum(c["nis"])), float(np.sum(2 * c["n_meas"])), p)


def pcrb_ric_sigma(geometry, options) -> np.ndarray:
    """Posterior Cramér–Rao bound σ per RIC axis (K, 6) for the study's truth and matched points."""
    x, t, T = geometry.x_true, geometry.t_s, geometry.T_cam_from_eci
    K = len(t)
    sd0 = options.initial_sigmas()
    Pb = np.diag(sd0**2)
    out = np.empty((K, 6))
    for k in range(K):
        if k > 0:
            dt = t[k] - t[k - 1]
            _, phi = propagate_state_stm(x[k - 1:k], dt, max_step_s=options.filter_step_s)
            Pb = phi[0] @ Pb @ phi[0].T
            if options.q_acc_m2_s3 > 0:
                Pb = Pb + white_acceleration_qd(dt, options.q_acc_m2_s3)
        pts = geometry.points_eci[k]
        if len(pts):
            m = len(pts)
            e_c, e_i, rho = los_predict(x[k:k + 1, :3], pts, T[k])
            H = np.zeros((3 * m, 6))
            H[:, :3] = los_jacobian_position(e_i, rho, T[k]).reshape(3 * m, 3)
            R = np.zeros((3 * m, 3 * m))
            for i in range(m):
                e = e_c[0, i]
                R[3 * i:3 * i + 3, 3 * i:3 * i + 3] = options.sigma_theta_rad**2 * (np.eye(3) - np.outer(e, e))
            G = skew_batch(e_c[0]).reshape(3 * m, 3)
            R += options.sigma_star_tracker_rad**2 * G @ G.T
            J = np.linalg.inv(Pb) + H.T @ np.linalg.pinv(R, rcond=1e-10, hermitian=True) @ H
            Pb = np.linalg.inv(J)
            Pb = 0.5 * (Pb + Pb.T)
        C = ric_axes(x[k])
        out[k, :3] = np.sqrt(np.diag(C @ Pb[:3, :3] @ C.T))
        out[k, 3:] = np.sqrt(np.diag(C @ Pb[3:, 3:] @ C.T))
    return out


def steady_state(summary, fraction: float = 0.2) -> dict:
    """Table-1 numbers: 3 x RMS over the last ``fraction`` of the span, per axis, for MC, filter and PCRB."""
    t = summary["t_s"].to_numpy()
    sel = t >= t[0] + (1.0 - fraction) * (t[-1] - t[0])
    row = {"window_start_s": float(t[sel][0]), "window_end_s": float(t[-1])}
    for a, u in AXES:
        for kind, prefix in (("mc", "mc_rms_"), ("filter", "filter_sig_"), ("pcrb", "pcrb_sig_")):
            name = f"{prefix}{a}_{u}"
            if name in summary.column_names:
                v = summary[name].to_numpy()[sel]
                row[f"{kind}_3sig_{a}_{u}"] = float(3.0 * np.sqrt(np.mean(v**2)))
    row["anees_mean"] = float(np.mean(summary["anees"].to_numpy()[sel]))
    return row
