r"""Scoring of the coastline-EKF Monte Carlo: Monte Carlo vs filter σ, ANEES/ANIS with χ² bands, the
posterior Cramér–Rao bound, and the steady-state numbers of Table 1 (Straub & Christian).

Theory
------
- ANEES at time k over N runs: :math:`\bar\epsilon_k = N^{-1}\sum_j \tilde x_{jk}^T P_{jk}^{-1}\tilde x_{jk}`.
  For a consistent filter :math:`N\bar\epsilon_k \sim \chi^2(6N)`, so the two-sided 99 % band is
  :math:`[\chi^2_{0.005}(6N)/N,\ \chi^2_{0.995}(6N)/N]` (Bar-Shalom, Li & Kirubarajan §5.4).
- ANIS likewise with :math:`2m_k` degrees of freedom per run at an image with :math:`m_k` LOS (the NIS uses
  :math:`S^+`, rank 2 per LOS). Innovations of a consistent filter are white, so the NIS summed over all
  images and runs is :math:`\chi^2(N\sum_k 2m_k)` (:func:`nis_total_test`).
- PCRB (Tichavský, Muravchik & Nehorai 1998, additive Gaussian noise): information recursion
  :math:`J_{k} = (\Phi_k J_{k-1}^{-1}\Phi_k^T + Q_k)^{-1} + H_k^T R_k^{+} H_k`, :math:`J_0 = P_0^{-1}`, with
  Φ and H (eq. 13, 17) evaluated on the *true* trajectory and the same matched points as the Monte Carlo.
  :math:`R_k^+` is the pseudo-inverse of the stacked rank-2m covariance (eq. 18 plus the shared star-tracker
  term), computed with ``numpy.linalg.pinv`` (independent of the filter's eq. 19 algebra). The deterministic
  truth makes the expectation trivial.
- Steady state (Table 1): the Monte Carlo RMS error per RIC axis over the last ``fraction`` of the time span,
  reported as 3σ, next to the filter's 3σ and the PCRB's 3σ over the same window.
"""

from __future__ import annotations

import numpy as np

from estimators.coastline.dynamics import propagate_state_stm, white_acceleration_qd
from estimators.coastline.los import los_jacobian_position, los_predict, skew_batch
from renderlab.studies.coastline_ekf.geometric import ric_axes

__all__ = ["AXES", "chi2_band", "per_time_summary", "pcrb_ric_sigma", "steady_state", "nis_total_test",
           "nis_band_test"]

AXES = [("r", "m"), ("i", "m"), ("c", "m"), ("vr", "mps"), ("vi", "mps"), ("vc", "mps")]
ERR = [f"err_{a}_{u}" for a, u in AXES]
SIG = [f"sig_{a}_{u}" for a, u in AXES]


def chi2_band(dof_per_run, n_runs: int, p: float = 0.99) -> tuple[np.ndarray, np.ndarray]:
    """Two-sided p band of the run-average of χ²(dof) variables: χ²_{(1∓p)/2}(N·dof)/N."""
    from scipy.stats import chi2

    dof = np.asarray(dof_per_run, dtype=np.float64) * n_runs
    a = 0.5 * (1.0 - p)
    with np.errstate(invalid="ignore"):
        lo = np.where(dof > 0, chi2.ppf(a, np.maximum(dof, 1)) / n_runs, np.nan)
        hi = np.where(dof > 0, chi2.ppf(1.0 - a, np.maximum(dof, 1)) / n_runs, np.nan)
    return lo, hi


def _columns(table) -> tuple[dict[str, np.ndarray], int, int]:
    runs = table["run"].to_numpy()
    N = len(np.unique(runs))
    K = len(runs) // N
    order = np.lexsort((table["t_s"].to_numpy(), runs))
    cols = {c: table[c].to_numpy()[order].reshape(N, K) for c in table.column_names}
    return cols, N, K


def per_time_summary(table, pcrb_sigma: np.ndarray | None = None, p: float = 0.99):
    """One row per time: MC mean and RMS error, mean filter σ, PCRB σ, ANEES/ANIS and their χ² bands.

    Parameters
    ----------
    table : pyarrow.Table
        The study's filter table (``run, t_s, err_*, sig_*, nees, nis, n_meas``), all runs on the same times.
    pcrb_sigma : ndarray (K, 6), optional
        From :func:`pcrb_ric_sigma`.
    """
    import pyarrow as pa

    c, N, K = _columns(table)
    # mean LOS count over runs (equal in the geometric mode; the image mode's can differ per run): the summed NIS
    # of N runs at one time is χ²(Σ 2 m_n) = χ²(N · 2 mean(m)), so the band below stays exact
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


def nis_band_test(total: float, dof: float, p: float = 0.99) -> dict:
    """A NIS sum ``total`` of ``dof`` degrees of freedom against its two-sided p band of χ²(dof)."""
    from scipy.stats import chi2

    lo, hi = chi2.ppf(0.5 * (1 - p), dof), chi2.ppf(0.5 * (1 + p), dof)
    return {"total": total, "dof": dof, "lo": lo, "hi": hi, "ratio": total / dof, "inside": bool(lo <= total <= hi)}


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
