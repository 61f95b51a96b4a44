"""Figures and summary of an unknown-satellite campaign, like Ivanov et al. (2018) Figs 5-7 and 13-14, over runs.

* Fig 5: stage-1 convergence of the initial centre-of-mass position and velocity errors, every run a line.
* Fig 6: inertia — convergence of the ratio errors, and the final I1/I3, I2/I3 of every run against the
  truth with the Cramér–Rao σ of eq. 7 as error bars (is the spread what the Fisher information says?).
* Fig 7: reference points — RMS error in LVLH at the epoch (gauge-free) and in the body frame, per run,
  against the paper's 3 cm.
* Fig 13: stage-2 relative centre-of-mass position and velocity errors against time (every run, and the
  RMS over runs).
* Fig 14: stage-2 body-rate errors per axis and the attitude error against time.

Everything is drawn from the campaign's tables (``scores``, ``stage1_history``, ``stage2``).
"""

from __future__ import annotations

import html
from pathlib import Path

import numpy as np

from renderlab.report.campaign_report import write_csv

#: scores summarised across runs: column → (label, unit scale, unit)
SCORES = {
    "point_lvlh_err_rms_m": ("reference points, RMS error in LVLH at the epoch", 100, "cm"),
    "point_lvlh_crlb_rms_m": ("reference points in LVLH, CRLB σ (RMS over points, eq. 7)", 100, "cm"),
    "point_err_rms_m": ("reference points, RMS error in the body frame", 100, "cm"),
    "point_err_rms_aligned_m": ("reference points, RMS error in the body frame, axes relabelled to truth", 100, "cm"),
    "point_shape_err_rms_m": ("reference points, RMS error after the best rotation", 100, "cm"),
    "r0_err_m": ("initial position error ‖r0‖", 100, "cm"),
    "v0_err_mps": ("initial velocity error ‖v0‖", 100, "cm/s"),
    "stage2_vel_rms_mps": ("stage 2: velocity RMS", 100, "cm/s"),
    "stage2_pos_rms_m": ("stage 2: position RMS", 100, "cm"),
    "w0_norm_est_deg_s": ("‖ω0‖ estimated", 1, "°/s"),
    "w0_norm_err_deg_s": ("‖ω0‖ error", 1, "°/s"),
    "w0_norm_crlb_deg_s": ("‖ω0‖ CRLB σ (eq. 7)", 1, "°/s"),
    "w0_lvlh_err_deg_s": ("ω0 error in LVLH (vector)", 1, "°/s"),
    "v0_crlb_mps": ("initial velocity CRLB σ (eq. 7)", 100, "cm/s"),
    "stage2_wx_rms_deg_s": ("stage 2: ωx RMS error", 1, "°/s"),
    "stage2_wy_rms_deg_s": ("stage 2: ωy RMS error", 1, "°/s"),
    "stage2_wz_rms_deg_s": ("stage 2: ωz RMS error", 1, "°/s"),
    "stage2_att_rms_deg": ("stage 2: attitude RMS error (principal axes)", 1, "°"),
    "stage2_att_rms_aligned_deg": ("stage 2: attitude RMS error, axes relabelled to truth", 1, "°"),
    "stage2_wx_rms_aligned_deg_s": ("stage 2: ωx RMS error, axes relabelled", 1, "°/s"),
    "stage2_wy_rms_aligned_deg_s": ("stage 2: ωy RMS error, axes relabelled", 1, "°/s"),
    "stage2_wz_rms_aligned_deg_s": ("stage 2: ωz RMS error, axes relabelled", 1, "°/s"),
    "err_ratio_12_aligned": ("I1/I3 error, axes relabelled to truth", 1, ""),
    "err_ratio_23_aligned": ("I2/I3 error, axes relabelled to truth", 1, ""),
    "err_ratio_12": ("I1/I3 error", 1, ""),
    "err_ratio_23": ("I2/I3 error", 1, ""),
    "err_moments_sorted_max": ("trace-normalised principal moments, max error (axis labels free)", 1, ""),
    "inertia_tensor_lvlh_err_max": ("trace-normalised inertia tensor in LVLH, max error", 1, ""),
    "ratio_sigma_1": ("I1/I3 CRLB σ (eq. 7)", 1, ""),
    "ratio_sigma_2": ("I2/I3 CRLB σ (eq. 7)", 1, ""),
    "stage1_rms_px": ("stage 1: residual RMS", 1, "px"),
    "database_points": ("database points", 1, ""),
    "rigidity_rejected": ("tracks rejected by the rigidity test", 1, ""),
}


def _np(t, name, dtype=float):
    return np.asarray(t.column(name).to_numpy(zero_copy_only=False), dtype)


def score_summary(scores) -> list[dict]:
    """Per score: runs, mean, std, median, 10th and 90th percentile (in the unit of :data:`SCORES`)."""
    rows = []
    for col, (label, scale, unit) in SCORES.items():
        if col not in scores.column_names:
            continue
        v = _np(scores, col) * scale
        v = v[np.isfinite(v)]
        if not len(v):
            continue
        p10, med, p90 = np.percentile(v, [10, 50, 90])
        rows.append({"score": col, "label": label, "unit": unit, "runs": len(v), "mean": float(v.mean()),
                     "std": float(v.std(ddof=1)) if len(v) > 1 else float("nan"), "median": float(med),
                     "p10": float(p10), "p90": float(p90)})
    from renderlab.studies.unknown_satellite.config import RUN_FLAGS

    for name in RUN_FLAGS:
        if f"flag_{name}" not in scores.column_names:
            continue
        on = _np(scores, f"flag_{name}", bool)
        rows.append({"score": f"flag_{name}", "label": f"runs flagged {name}", "unit": "runs", "runs": len(on),
                     "mean": float(np.mean(on)), "median": float(np.sum(on))})
    return rows


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _by_run(t, cols):
    runs = _np(t, "run", np.int64)
    for r in np.unique(runs):
        sel = runs == r
        yield r, {c: _np(t, c)[sel] for c in cols}


def fig5_convergence(hist, path: Path) -> None:
    plt = _plt()
    fig, ax = plt.subplots(1, 2, figsize=(9, 3.5), constrained_layout=True)
    cols = ["iteration"] + [f"err_r0_{a}_m" for a in "xyz"] + [f"err_v0_{a}_mps" for a in "xyz"]
    for _, d in _by_run(hist, cols):
        er = np.linalg.norm([d[f"err_r0_{a}_m"] for a in "xyz"], axis=0)
        ev = np.linalg.norm([d[f"err_v0_{a}_mps"] for a in "xyz"], axis=0)
        ax[0].semilogy(d["iteration"], 100 * er, lw=0.7, alpha=0.6)
        ax[1].semilogy(d["iteration"], 100 * ev, lw=0.7, alpha=0.6)
    ax[0].set(xlabel="accepted iterate", ylabel="‖r0 error‖ (cm)", title="(a) initial CM position (Fig. 5a)")
    ax[1].set(xlabel="accepted iterate", ylabel="‖v0 error‖ (cm/s)", title="(b) initial velocity (Fig. 5b)")
    for a in ax:
        a.grid(alpha=0.3, which="both")
    fig.savefig(path, dpi=110)
    plt.close(fig)


def fig6_inertia(hist, scores, path: Path) -> None:
    plt = _plt()
    fig, ax = plt.subplots(1, 2, figsize=(10, 3.8), constrained_layout=True)
    for _, d in _by_run(hist, ["iteration", "err_ratio12", "err_ratio23"]):
        ax[0].plot(d["iteration"], d["err_ratio12"], "C0", lw=0.6, alpha=0.6)
        ax[0].plot(d["iteration"], d["err_ratio23"], "C1", lw=0.6, alpha=0.6)
    ax[0].plot([], [], "C0", label="I1/I3")
    ax[0].plot([], [], "C1", label="I2/I3")
    ax[0].axhline(0, color="k", lw=0.5)
    ax[0].set(xlabel="accepted iterate", ylabel="ratio error", title="inertia ratios, convergence (cf. Fig. 6)")
    ax[0].legend(fontsize=8)
    al = "ratio_I1_I3_aligned" in scores.column_names
    e1 = _np(scores, "ratio_I1_I3_aligned" if al else "ratio_I1_I3_est")
    e2 = _np(scores, "ratio_I2_I3_aligned" if al else "ratio_I2_I3_est")
    s1, s2 = _np(scores, "ratio_sigma_1"), _np(scores, "ratio_sigma_2")
    fb = _np(scores, "flag_inertia_boundary", bool)
    for m, mk, lab in ((~fb, "o", "free solve"), (fb, "s", "physical re-solve (boundary)")):
        if m.any():
            ax[1].errorbar(e1[m], e2[m], xerr=s1[m], yerr=s2[m], fmt=mk, ms=4, lw=0.6, alpha=0.7, label=lab)
    t1, t2 = _np(scores, "ratio_I1_I3_true"), _np(scores, "ratio_I2_I3_true")
    ax[1].plot(t1, t2, "k*", ms=12, label="truth")
    x = np.linspace(0, 2, 50)
    ax[1].plot(x, 1 - x, "k:", lw=0.8, label="I1+I2 = I3 (flat body)")
    lo = np.nanmin(np.r_[e1, e2, t1, t2]) - 0.2
    hi = np.nanmax(np.r_[e1, e2, t1, t2]) + 0.2
    ax[1].set(xlim=(max(lo, 0), hi), ylim=(max(lo, 0), hi), xlabel="I1/I3", ylabel="I2/I3",
              title="final ratios" + (" (axes relabelled to truth)" if al else "") + ", bars: CRLB 1σ")
    ax[1].legend(fontsize=7)
    for a in ax:
        a.grid(alpha=0.3)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def fig7_points(hist, scores, path: Path) -> None:
    plt = _plt()
    fig, ax = plt.subplots(1, 2, figsize=(10, 3.6), constrained_layout=True)
    for _, d in _by_run(hist, ["iteration", "err_points_rms_m"]):
        ax[0].semilogy(d["iteration"], 100 * d["err_points_rms_m"], lw=0.7, alpha=0.6)
    ax[0].set(xlabel="accepted iterate", ylabel="RMS point error, body frame (cm)",
              title="reference points, convergence (cf. Fig. 7)")
    runs = _np(scores, "run", np.int64)
    ax[1].semilogy(runs, 100 * _np(scores, "point_lvlh_err_rms_m"), "o", label="LVLH at the epoch (gauge-free)")
    ax[1].semilogy(runs, 100 * _np(scores, "point_err_rms_m"), "s", mfc="none", label="body frame (principal axes)")
    if "point_err_rms_aligned_m" in scores.column_names:
        ax[1].semilogy(runs, 100 * _np(scores, "point_err_rms_aligned_m"), "^", mfc="none",
                       label="body frame, axes relabelled to truth")
    ax[1].axhline(3.0, color="k", ls="--", lw=0.8, label="paper: 3 cm")
    ax[1].set(xlabel="run", ylabel="RMS error (cm)", title="reference points, final, per run")
    ax[1].legend(fontsize=7)
    for a in ax:
        a.grid(alpha=0.3, which="both")
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _rms_over_runs(t, col):
    ts = _np(t, "t_s")
    v = _np(t, col)
    u = np.unique(ts)
    return u, np.array([np.sqrt(np.nanmean(v[ts == x] ** 2)) for x in u])


def fig13_position(s2, path: Path) -> None:
    plt = _plt()
    fig, ax = plt.subplots(1, 2, figsize=(10, 3.6), constrained_layout=True)
    for k, (q, scale, unit) in enumerate((("r", 100, "cm"), ("v", 100, "cm/s"))):
        cols = [f"err_{q}{a}_{'m' if q == 'r' else 'mps'}" for a in "xyz"]
        for _, d in _by_run(s2, ["t_s"] + cols):
            ax[k].plot(d["t_s"], scale * np.linalg.norm([d[c] for c in cols], axis=0), lw=0.5, alpha=0.4)
        u = np.unique(_np(s2, "t_s"))
        tot = np.sqrt(sum(_rms_over_runs(s2, c)[1] ** 2 for c in cols))
        ax[k].plot(u, scale * tot, "k", lw=1.5, label="RMS over runs")
        ax[k].legend(fontsize=7)
        ax[k].grid(alpha=0.3)
    ax[0].set(xlabel="t (s)", ylabel="‖position error‖ (cm)", title="stage 2: CM position, LVLH (cf. Fig. 13)")
    ax[1].axhline(1.0, color="k", ls="--", lw=0.8)
    ax[1].set(xlabel="t (s)", ylabel="‖velocity error‖ (cm/s)", title="stage 2: velocity (dashed: paper ≈1 cm/s)")
    fig.savefig(path, dpi=110)
    plt.close(fig)


def fig14_attitude(s2, path: Path) -> None:
    plt = _plt()
    fig, ax = plt.subplots(1, 2, figsize=(10, 3.6), constrained_layout=True)
    for i, a in enumerate("xyz"):
        c = f"err_w{a}_aligned_deg_s" if f"err_w{a}_aligned_deg_s" in s2.column_names else f"err_w{a}_deg_s"
        u, r = _rms_over_runs(s2, c)
        ax[0].plot(u, r, f"C{i}", lw=1.5, label=f"ω{a} RMS over runs")
    ax[0].set(xlabel="t (s)", ylabel="°/s", title="stage 2: body-rate error (cf. Fig. 14)")
    ax[0].legend(fontsize=7)
    att = "err_att_aligned_deg" if "err_att_aligned_deg" in s2.column_names else "err_att_deg"
    for _, d in _by_run(s2, ["t_s", att]):
        ax[1].semilogy(d["t_s"], d[att], lw=0.5, alpha=0.5)
    ax[1].set(xlabel="t (s)", ylabel="°", title="stage 2: principal-axes attitude error"
              + (" (relabelled)" if att != "err_att_deg" else ""))
    for a in ax:
        a.grid(alpha=0.3)
    fig.savefig(path, dpi=110)
    plt.close(fig)


FIGURES = ("fig5_convergence", "fig6_inertia", "fig7_points", "fig13_stage2_position", "fig14_stage2_attitude")


def campaign_figures(tables: dict, out_dir: Path, prefix: str = "unknown_satellite_") -> list[str]:
    """Draw the figures that the tables allow; return their file names."""
    out_dir = Path(out_dir)
    done = []
    sc, hist, s2 = tables.get("scores"), tables.get("stage1_history"), tables.get("stage2")
    jobs = [("fig5_convergence", hist is not None, lambda p: fig5_convergence(hist, p)),
            ("fig6_inertia", hist is not None and sc is not None, lambda p: fig6_inertia(hist, sc, p)),
            ("fig7_points", hist is not None and sc is not None, lambda p: fig7_points(hist, sc, p)),
            ("fig13_stage2_position", s2 is not None, lambda p: fig13_position(s2, p)),
            ("fig14_stage2_attitude", s2 is not None, lambda p: fig14_attitude(s2, p))]
    for name, ok, draw in jobs:
        if ok:
            draw(out_dir / f"{prefix}{name}.png")
            done.append(f"{prefix}{name}.png")
    return done


def campaign_sections(tables: dict, out_dir: Path) -> list[tuple[str, str]]:
    """HTML sections of the report (figures + score summary, written as ``unknown_satellite_summary.csv`` and,
    where the generic report wrote none, ``summary.csv``)."""
    if "scores" not in tables:
        return []
    rows = score_summary(tables["scores"])
    write_csv(out_dir / "unknown_satellite_summary.csv", rows)
    if not (out_dir / "summary.csv").exists():  # the page links summary.csv; no measurement table wrote one
        write_csv(out_dir / "summary.csv", rows)
    figs = campaign_figures(tables, out_dir)

    def fmt(v):
        return f"{v:.4g}" if isinstance(v, float) else html.escape(str(v))
    cols = ["label", "unit", "runs", "mean", "std", "median", "p10", "p90"]
    table = ("<table><tr>" + "".join(f"<th>{c}</th>" for c in cols) + "</tr>"
             + "".join("<tr>" + "".join(f"<td>{fmt(r.get(c, ''))}</td>" for c in cols) + "</tr>" for r in rows)
             + "</table>")
    body = ("<p>Scores over runs (paper: reference points 3 cm, velocity ≈1 cm/s, ‖ω‖ 4.24 °/s, gyro 4.5). "
            "Table: <a href='unknown_satellite_summary.csv'>unknown_satellite_summary.csv</a>.</p>" + table
            + "".join(f'<p><img src="{f}" alt="{f}"></p>' for f in figs))
    return [("Unknown satellite: scores and figures (Ivanov et al. Figs 5-7, 13-14)", body)]
