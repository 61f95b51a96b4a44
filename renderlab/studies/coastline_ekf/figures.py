"""Figures of the coastline-EKF Monte Carlo in the style of Straub & Christian Figs. 5-9.

Each error figure has the radial, in-track and cross-track axes as rows and position (m) / velocity (mm/s) as
columns: a sample of run errors (thin), the Monte Carlo ±3σ (black), the filter's ±3σ (grey, dashed; RMS of
the runs' σ) and the PCRB's 3σ (red, dotted). Ticks along the bottom mark images with matched coastline.
A second figure shows ANEES and ANIS with their 99 % χ² bands.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["plot_errors", "plot_consistency"]

_AXES = [("r", "radial"), ("i", "in-track"), ("c", "cross-track")]


def _mpl():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_errors(runs_table, summary, path: Path, title: str, n_sample_runs: int = 25) -> Path:
    """Figs. 5-9 style: errors with filter 3σ, Monte Carlo 3σ and PCRB 3σ (PNG at ``path``)."""
    plt = _mpl()
    t_h = summary["t_s"].to_numpy() / 3600.0
    runs = runs_table["run"].to_numpy()
    sample = np.unique(runs)[:n_sample_runs]
    fig, axs = plt.subplots(3, 2, figsize=(11, 8), sharex=True)
    for row, (a, name) in enumerate(_AXES):
        for col, (prefix, unit, scale, label) in enumerate([("", "m", 1.0, "m"), ("v", "mps", 1e3, "mm/s")]):
            ax = axs[row, col]
            key = f"{prefix}{a}_{unit}"
            for k in sample:
                sel = runs == k
                ax.plot(runs_table["t_s"].to_numpy()[sel] / 3600.0, scale * runs_table[f"err_{key}"].to_numpy()[sel],
                        color="tab:blue", lw=0.4, alpha=0.35)
            mc = scale * summary[f"mc_rms_{key}"].to_numpy()
            fs = scale * summary[f"filter_sig_{key}"].to_numpy()
            ax.plot(t_h, 3 * mc, "k", lw=1.3, label="Monte Carlo 3σ")
            ax.plot(t_h, -3 * mc, "k", lw=1.3)
            ax.plot(t_h, 3 * fs, color="0.55", ls="--", lw=1.3, label="filter 3σ")
            ax.plot(t_h, -3 * fs, color="0.55", ls="--", lw=1.3)
            if f"pcrb_sig_{key}" in summary.column_names:
                pc = scale * summary[f"pcrb_sig_{key}"].to_numpy()
                ax.plot(t_h, 3 * pc, color="tab:red", ls=":", lw=1.2, label="PCRB 3σ")
                ax.plot(t_h, -3 * pc, color="tab:red", ls=":", lw=1.2)
            lim = 3.5 * max(np.nanmax(mc[len(mc) // 5:]), np.nanmax(fs[len(fs) // 5:]))
            ax.set_ylim(-lim, lim)
            img = summary["n_meas"].to_numpy() > 0
            ax.plot(t_h[img], np.full(img.sum(), -0.97 * lim), "|", color="tab:green", ms=4)
            ax.set_ylabel(f"{name} [{label}]")
            ax.grid(alpha=0.3)
    axs[0, 0].set_title("position error")
    axs[0, 1].set_title("velocity error")
    axs[-1, 0].set_xlabel("time [h]")
    axs[-1, 1].set_xlabel("time [h]")
    axs[0, 1].legend(loc="upper right", fontsize=8)
    fig.suptitle(f"{title} — {len(np.unique(runs))} runs (y-range set by the last 80 %; green ticks: images with "
                 f"coastline)", fontsize=10)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_consistency(summary, path: Path, title: str) -> Path:
    """ANEES (6 dof) and ANIS (2 dof per LOS) against time with their 99 % χ² bands."""
    plt = _mpl()
    t_h = summary["t_s"].to_numpy() / 3600.0
    n = int(summary["n_runs"].to_numpy()[0])
    fig, axs = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    axs[0].plot(t_h, summary["anees"].to_numpy(), "k.", ms=3, label="ANEES")
    axs[0].fill_between(t_h, summary["anees_lo"].to_numpy(), summary["anees_hi"].to_numpy(), color="tab:green",
                        alpha=0.25, label=f"99 % χ²(6·{n})/{n} band")
    axs[0].axhline(6.0, color="0.5", lw=0.8)
    axs[0].set_ylabel("ANEES")
    img = summary["n_meas"].to_numpy() > 0
    m = summary["n_meas"].to_numpy()[img]
    axs[1].plot(t_h[img], summary["anis"].to_numpy()[img] / (2 * m), "k.", ms=3, label="ANIS / (2m)")
    axs[1].vlines(t_h[img], summary["anis_lo"].to_numpy()[img] / (2 * m), summary["anis_hi"].to_numpy()[img] / (2 * m),
                  color="tab:green", alpha=0.45, lw=2.0, label="99 % band of that image (2m dof)")
    axs[1].axhline(1.0, color="0.5", lw=0.8)
    axs[1].set_ylabel("ANIS / dof")
    axs[1].set_xlabel("time [h]")
    for ax in axs:
        ax.legend(fontsize=8, loc="upper right")
        ax.grid(alpha=0.3)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
