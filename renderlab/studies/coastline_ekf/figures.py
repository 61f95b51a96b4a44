"""Figures of the coastline-EKF Monte Carlo in the style of Straub & Christian Figs. 5-9 (report style: Okabe–Ito,
units, legends, PNG): per RIC axis the sampled run errors, the Monte Carlo, filter and PCRB ±3σ and the image ticks;
ANEES and ANIS against their 99 % χ² bands.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from renderlab.report import style
from renderlab.report.axes import plain_log
from renderlab.report.filter_section import time_unit

__all__ = ["plot_errors", "plot_consistency", "time_unit"]

_AXES = [("r", "radial"), ("i", "in-track"), ("c", "cross-track")]
_KINDS = [("", "m", 1.0, "m", "position"), ("v", "mps", 1e3, "mm/s", "velocity")]
RUN, MC, FILTER, PCRB, IMAGE = style.OKABE_ITO[0], "#000000", style.OKABE_ITO[1], style.OKABE_ITO[2], style.OKABE_ITO[4]


def _band(ax, t, half, **kw):
    """Plot ``±half`` against ``t`` (one legend entry)."""
    ax.plot(t, half, **kw)
    ax.plot(t, -half, **{k: v for k, v in kw.items() if k != "label"})


def _error_panel(ax, runs_table, summary, sample, key: str, scale: float, t_div: float) -> None:
    """One axis of :func:`plot_errors`: sampled runs, MC / filter / PCRB ±3σ, image ticks; y from the last 80 %."""
    t = summary["t_s"].to_numpy() / t_div
    runs, t_run = runs_table["run"].to_numpy(), runs_table["t_s"].to_numpy() / t_div
    err = runs_table[f"err_{key}"].to_numpy()
    xs, ys = [], []
    for k in sample:                                    # one line, runs separated by NaN (fast to draw)
        sel = runs == k
        xs += [t_run[sel], [np.nan]]
        ys += [scale * err[sel], [np.nan]]
    if xs:
        ax.plot(np.concatenate(xs), np.concatenate(ys), color=RUN, lw=0.4, alpha=0.35, rasterized=True)
    mc = scale * summary[f"mc_rms_{key}"].to_numpy()
    fs = scale * summary[f"filter_sig_{key}"].to_numpy()
    _band(ax, t, 3 * mc, color=MC, lw=1.3)
    _band(ax, t, 3 * fs, color=FILTER, ls="--", lw=1.3)
    if f"pcrb_sig_{key}" in summary.column_names:
        _band(ax, t, 3 * scale * summary[f"pcrb_sig_{key}"].to_numpy(), color=PCRB, ls=":", lw=1.3)
    tail = slice(len(mc) // 5, None)
    lim = 3.5 * max(np.nanmax(mc[tail]), np.nanmax(fs[tail]))
    ax.set_ylim(-lim, lim)
    img = summary["n_meas"].to_numpy() > 0
    ax.plot(t[img], np.full(img.sum(), -0.97 * lim), "|", color=IMAGE, ms=4)
    ax.grid(alpha=0.3)


def plot_errors(runs_table, summary, path: Path, title: str, unit: tuple, n_sample_runs: int = 25) -> list[str]:
    """Figs. 5-9 style: the first ``n_sample_runs`` runs of ``runs_table`` (``run, t_s, err_*``; may be a sample of
    the runs) as thin lines with the Monte Carlo, filter and PCRB ±3σ of ``summary`` (:func:`.scoring.
    per_time_summary` of all runs) → the PNG and SVG file names (SVG None unless ``renderlab report --svg``)."""
    plt = style.plt()
    div, tname = unit
    runs = runs_table["run"].to_numpy()
    sample = np.unique(runs)[:n_sample_runs]
    n_all = int(summary["n_runs"].to_numpy()[0])
    fig, axs = plt.subplots(3, 2, figsize=(11, 8.4), sharex=True, constrained_layout=True)
    for row, (a, name) in enumerate(_AXES):
        for col, (prefix, u, scale, ulabel, kind) in enumerate(_KINDS):
            _error_panel(axs[row, col], runs_table, summary, sample, f"{prefix}{a}_{u}", scale, div)
            axs[row, col].set_ylabel(f"{name} {kind} error ({ulabel})")
    for col, (*_, kind) in enumerate(_KINDS):
        axs[0, col].set_title(f"{kind} error")
        axs[-1, col].set_xlabel(f"time ({tname})")
    handles = [plt.Line2D([], [], color=RUN, lw=0.8, label=f"run error ({len(sample)} of {n_all} runs drawn)"),
               plt.Line2D([], [], color=MC, lw=1.3, label=f"Monte Carlo ±3σ (all {n_all} runs)"),
               plt.Line2D([], [], color=FILTER, ls="--", lw=1.3, label=f"filter ±3σ (RMS over {n_all} runs)")]
    if "pcrb_sig_r_m" in summary.column_names:
        handles.append(plt.Line2D([], [], color=PCRB, ls=":", lw=1.3, label="PCRB ±3σ"))
    handles.append(plt.Line2D([], [], color=IMAGE, marker="|", ls="none", label="image with matched coastline"))
    fig.legend(handles=handles, loc="outside lower center", ncol=len(handles), fontsize=8, frameon=False)
    fig.suptitle(f"{title}\n{len(sample)} of {n_all} runs drawn; the ±3σ curves use all {n_all} runs; "
                 "y-range set by the last 80 % of the span")
    return style.save(fig, Path(path).with_suffix(""))


def _consistency_panel(ax, t, value, lo, hi, label: str, band_label: str, per_time_band: bool) -> None:
    inside = (value >= lo) & (value <= hi)
    if per_time_band:
        ax.vlines(t, lo, hi, color=PCRB, alpha=0.45, lw=2.0, label=band_label)
    else:
        ax.fill_between(t, lo, hi, color=PCRB, alpha=0.25, label=band_label)
    ax.plot(t[inside], value[inside], ".", color=MC, ms=4, label=f"{label}, inside its band")
    if (~inside).any():
        ax.plot(t[~inside], value[~inside], "x", color=FILTER, ms=5, label=f"{label}, outside its band")
    ax.legend(fontsize=8, loc="upper left")
    ax.grid(alpha=0.3)


def plot_consistency(summary, path: Path, title: str, unit: tuple[float, str]) -> list[str]:
    """ANEES (6 dof) and ANIS per dof (2 dof per LOS) of ``summary`` against time with their 99 % χ² bands → the
    PNG and SVG file names (as :func:`plot_errors`)."""
    plt = style.plt()
    div, tname = unit
    t = summary["t_s"].to_numpy() / div
    n = int(summary["n_runs"].to_numpy()[0])
    fig, axs = plt.subplots(2, 1, figsize=(10, 6.4), sharex=True, constrained_layout=True)
    _consistency_panel(axs[0], t, summary["anees"].to_numpy(), summary["anees_lo"].to_numpy(),
                       summary["anees_hi"].to_numpy(), "ANEES", f"99 % χ²(6·{n})/{n} band", False)
    axs[0].axhline(6.0, color="0.5", lw=0.8)
    axs[0].set_ylabel("ANEES (6 dof)")
    if np.nanmax(summary["anees"].to_numpy()) > 3 * np.nanmax(summary["anees_hi"].to_numpy()):
        plain_log(axs[0])  # far outside its band: a log axis keeps the band visible
    img = summary["n_meas"].to_numpy() > 0
    dof = 2 * summary["n_meas"].to_numpy()[img]
    _consistency_panel(axs[1], t[img], summary["anis"].to_numpy()[img] / dof, summary["anis_lo"].to_numpy()[img] / dof,
                       summary["anis_hi"].to_numpy()[img] / dof, "ANIS / dof", "99 % band of that image (2m dof)", True)
    axs[1].axhline(1.0, color="0.5", lw=0.8)
    axs[1].set_ylabel("ANIS per dof (2 dof per LOS)")
    axs[1].set_xlabel(f"time ({tname})")
    fig.suptitle(f"{title}: filter consistency over {n} runs (grey line: the expected value)")
    return style.save(fig, Path(path).with_suffix(""))
