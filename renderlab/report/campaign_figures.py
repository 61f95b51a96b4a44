"""Figures of a campaign report, drawn from the tables only (matplotlib, Agg).

Δs/Δl scatter per method with the bias and the 1σ/3σ covariance ellipses (the layout of Wright et al.
Fig. 12), error against the truth's fractional pixel position (the sub-pixel interpolation bias of
the correlation peak finder), no-result rates with Wilson intervals, noise over the registration CRLB,
and bias/noise against each covariate (phase, GSD ratio, shadow fraction, albedo contrast, range).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from renderlab.campaign.scoring import no_result_mask


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _col(t, name, dtype=float):
    return np.asarray(t.column(name).to_numpy(zero_copy_only=False), dtype)


def _methods(t):
    return sorted(set(_col(t, "method", object)))


def covariance_ellipse(cov: np.ndarray, k: float = 1.0, n: int = 100) -> np.ndarray:
    """Points (n, 2) of the k-σ ellipse of a 2×2 covariance, centred at 0."""
    w, v = np.linalg.eigh(cov)
    a = np.linspace(0, 2 * np.pi, n)
    return (v @ (k * np.sqrt(np.clip(w, 0, None))[:, None] * np.vstack([np.cos(a), np.sin(a)]))).T


def scatter(t, path: Path) -> None:
    plt = _plt()
    ms = _methods(t)
    fig, axes = plt.subplots(1, len(ms), figsize=(4.2 * len(ms), 4.2), squeeze=False, constrained_layout=True)
    meth = _col(t, "method", object)
    es, el = _col(t, "err_s"), _col(t, "err_l")
    ok = ~no_result_mask(t) & np.isfinite(es) & np.isfinite(el)  # a result with a truth (visible landmark)
    lim = np.nanpercentile(np.abs(np.r_[es[ok], el[ok]]), 99.5) * 1.2 if ok.any() else 1.0
    for ax, m in zip(axes[0], ms):
        sel = ok & (meth == m)
        x, y = es[sel], el[sel]
        ax.scatter(x, y, s=6, alpha=0.5, color="tab:blue", label=f"{sel.sum()} results")
        if sel.sum() >= 3:
            mu, cov = np.array([x.mean(), y.mean()]), np.cov(np.vstack([x, y]))
            for k, ls in ((1, "-"), (3, "--")):
                e = covariance_ellipse(cov, k) + mu
                ax.plot(e[:, 0], e[:, 1], ls, color="tab:red", lw=1.2, label=f"{k}σ")
            ax.plot(*mu, "x", color="tab:red", ms=9, mew=2, label=f"bias ({mu[0]:+.3f}, {mu[1]:+.3f}) px")
        ax.axhline(0, color="k", lw=0.5)
        ax.axvline(0, color="k", lw=0.5)
        nores = int((no_result_mask(t) & (meth == m)).sum())
        ax.set(title=f"{m}: {nores} no result", xlabel="Δsample = meas − truth (px)",
               ylabel="Δline (px)", xlim=(-lim, lim), ylim=(-lim, lim), aspect="equal")
        ax.legend(fontsize=7, loc="upper right")
    fig.savefig(path, dpi=110)
    plt.close(fig)


def fractional_shift(t, path: Path, bins: int = 10) -> None:
    plt = _plt()
    ok = ~no_result_mask(t)
    meth = _col(t, "method", object)
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8), constrained_layout=True)
    edges = np.linspace(-0.5, 0.5, bins + 1)
    for ax, axis in zip(axes, "sl"):
        truth, err = _col(t, f"truth_{axis}"), _col(t, f"err_{axis}")
        frac = truth - np.round(truth)
        for m in _methods(t):
            sel = ok & (meth == m)
            ax.plot(frac[sel], err[sel], ".", ms=3, alpha=0.3)
            idx = np.clip(np.digitize(frac[sel], edges) - 1, 0, bins - 1)
            mean = [np.mean(err[sel][idx == b]) if np.any(idx == b) else np.nan for b in range(bins)]
            ax.plot(0.5 * (edges[1:] + edges[:-1]), mean, "-o", ms=4, label=f"{m} (bin mean)")
        ax.axhline(0, color="k", lw=0.5)
        ax.set(xlabel=f"fractional part of truth {axis} (px)", ylabel=f"Δ{'sample' if axis == 's' else 'line'} (px)")
        ax.legend(fontsize=7)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def failures(summary_rows: list[dict], path: Path) -> None:
    plt = _plt()
    rows = [r for r in summary_rows if r["axis"] == "s"]
    fig, ax = plt.subplots(figsize=(1.6 + 1.2 * len(rows), 3.4), constrained_layout=True)
    x = np.arange(len(rows))
    rate = np.array([r["no_result_rate"] for r in rows])
    err = np.array([[r["no_result_rate"] - r["no_result_lo"], r["no_result_hi"] - r["no_result_rate"]] for r in rows]).T
    ax.bar(x, 100 * rate, color="tab:orange")
    ax.errorbar(x, 100 * rate, yerr=100 * np.clip(err, 0, None), fmt="none", color="k", capsize=4)
    ax.set_xticks(x, [r["method"] for r in rows])
    ax.set(ylabel="no-result rate (%), 95 % Wilson CI", ylim=(0, max(5.0, 110 * float(np.nanmax(rate, initial=0)))))
    fig.savefig(path, dpi=110)
    plt.close(fig)


def crlb_ratio(summary_rows: list[dict], path: Path) -> None:
    plt = _plt()
    rows = [r for r in summary_rows if np.isfinite(r.get("std_over_crlb", np.nan))]
    fig, ax = plt.subplots(figsize=(1.6 + 1.0 * max(1, len(rows)), 3.4), constrained_layout=True)
    if rows:
        x = np.arange(len(rows))
        ax.bar(x, [r["std_over_crlb"] for r in rows], color="tab:green")
        ax.set_xticks(x, [f"{r['method']}\n{r['axis']}" for r in rows])
        ax.set_yscale("log")
    ax.axhline(1, color="k", lw=0.8)
    ax.set(ylabel="noise / registration CRLB")
    fig.savefig(path, dpi=110)
    plt.close(fig)


def breakdowns(rows: list[dict], path: Path) -> bool:
    """Bias and noise vs each covariate; False if no covariate was present."""
    plt = _plt()
    by = sorted({r["by"] for r in rows})
    if not by:
        return False
    fig, axes = plt.subplots(2, len(by), figsize=(3.4 * len(by), 5.6), squeeze=False, constrained_layout=True)
    for j, col in enumerate(by):
        sub = [r for r in rows if r["by"] == col]
        for m in sorted({r["method"] for r in sub}):
            for axis, ls in (("s", "-"), ("l", "--")):
                rr = [r for r in sub if r["method"] == m and r["axis"] == axis]
                c = [r["center"] for r in rr]
                axes[0, j].errorbar(c, [r["mean"] for r in rr], yerr=[[r["mean"] - r["mean_lo"] for r in rr],
                                    [r["mean_hi"] - r["mean"] for r in rr]], fmt=ls + "o", ms=3, capsize=2,
                                    label=f"{m} {axis}")
                axes[1, j].plot(c, [r["std"] for r in rr], ls + "o", ms=3, label=f"{m} {axis}")
        axes[0, j].set(title=col, ylabel="bias (px)" if j == 0 else None)
        axes[1, j].set(xlabel=col, ylabel="noise σ (px)" if j == 0 else None)
        axes[0, j].axhline(0, color="k", lw=0.5)
    axes[0, 0].legend(fontsize=6)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


def filter_errors(t, path: Path) -> None:
    """Filter studies: every err_* column against time, each run a thin line."""
    plt = _plt()
    cols = [c for c in t.column_names if c.startswith("err_")]
    fig, axes = plt.subplots(len(cols), 1, figsize=(8, 1.8 * len(cols)), squeeze=False, sharex=True,
                             constrained_layout=True)
    runs, ts = _col(t, "run", np.int64), _col(t, "t_s")
    for ax, c in zip(axes[:, 0], cols):
        v = _col(t, c)
        for r in np.unique(runs):
            sel = runs == r
            ax.plot(ts[sel], v[sel], lw=0.5, alpha=0.5)
        sig = "sig_" + c[4:]
        if sig in t.column_names:
            uniq = np.unique(ts)
            s3 = np.array([3 * np.nanmean(_col(t, sig)[ts == u]) for u in uniq])
            ax.plot(uniq, s3, "k--", lw=1, label="filter 3σ")
            ax.plot(uniq, -s3, "k--", lw=1)
        ax.set(ylabel=c)
    axes[-1, 0].set(xlabel="t (s)")
    fig.savefig(path, dpi=110)
    plt.close(fig)
