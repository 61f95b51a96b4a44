"""Figures of landmark measurement tables (matplotlib, Agg), drawn from the tables only, in the report style
(:mod:`renderlab.report.style`: one colour per method everywhere, units on every axis, a legend wherever more than
one line is drawn, PNG; SVG with ``renderlab report --svg``).

- :func:`fig12`: Δsample vs Δline per method on shared axes, the bias (mean) point and robust 1σ/3σ ellipses
  (Wright et al., Fig. 12), with the count of points outside the axes printed in each panel.
- :func:`pixel_locking`: error against the truth's fractional pixel position (the sub-pixel peak step's bias).
- :func:`reasons`: share of rows per no-result reason and method.
- :func:`breakdowns`: bias and robust σ against each covariate with more than one bin (others are left out, noted).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from renderlab.report import style
from renderlab.report.landmark_stats import has_result, robust_cov, robust_sigma


def _col(t, name, dtype=float):
    return np.asarray(t.column(name).to_numpy(zero_copy_only=False), dtype)


def ellipse(cov: np.ndarray, k: float, n: int = 120) -> np.ndarray:
    """Points (n, 2) of the k-σ ellipse of a 2×2 covariance, centred at 0."""
    w, v = np.linalg.eigh(cov)
    a = np.linspace(0, 2 * np.pi, n)
    return (v @ (k * np.sqrt(np.clip(w, 0, None))[:, None] * np.vstack([np.cos(a), np.sin(a)]))).T


def fig12(table, stem: Path, mask=None, title: str = "") -> list[str]:
    """The Fig. 12 panel row (module docstring); returns the file names written."""
    plt = style.plt()
    mask = np.ones(table.num_rows, bool) if mask is None else np.asarray(mask, bool)
    meth = _col(table, "method", object)
    methods = sorted(set(meth[mask]))
    colors = style.method_colors(_col(table, "method", object))
    es, el = _col(table, "err_s"), _col(table, "err_l")
    ok = has_result(table) & mask
    lim = 0.5
    for m in methods:  # shared, robust limits: |median| + 5 robust σ of the widest method
        s = ok & (meth == m)
        if s.sum() >= 3:
            lim = max(lim, *(abs(float(np.median(v[s]))) + 5 * robust_sigma(v[s]) for v in (es, el)))
    fig, axes = plt.subplots(1, len(methods), figsize=(3.7 * len(methods) + 0.5, 4.4), squeeze=False,
                             sharex=True, sharey=True, layout="compressed")
    for ax, m in zip(axes[0], methods):
        s = ok & (meth == m)
        x, y = es[s], el[s]
        c = colors[m]
        out = int(np.sum((np.abs(x) > lim) | (np.abs(y) > lim)))
        n = int(s.sum())
        ax.scatter(np.clip(x, -lim, lim), np.clip(y, -lim, lim), s=4 if n > 500 else 14,
                   alpha=float(np.clip(60.0 / max(n, 1), 0.12, 0.9)), color=c, lw=0, rasterized=True)
        head = f"{m}: {n} results"
        if n >= 3:
            centre, cov = robust_cov(x, y)
            for k, ls in ((1, "-"), (3, "--")):
                e = ellipse(cov, k) + centre
                ax.plot(e[:, 0], e[:, 1], ls, color="k", lw=1.1, label=f"robust {k}σ ellipse")
            mu = (float(x.mean()), float(y.mean()))
            ax.plot(*mu, "X", color="k", mec="w", ms=9, label="bias (mean)")
            head += f"\nbias ({mu[0]:+.3f}, {mu[1]:+.3f}) px"
        ax.axhline(0, color="0.5", lw=0.5)
        ax.axvline(0, color="0.5", lw=0.5)
        ax.set(xlim=(-lim, lim), ylim=(-lim, lim), aspect="equal", xlabel=style.label("err_s"))
        ax.set_title(head, color=c, fontweight="bold")
        ax.text(0.02, 0.02, f"{out} outside the axes\n(drawn on the edge)", transform=ax.transAxes, fontsize=8,
                va="bottom")
    if axes[0, -1].get_legend_handles_labels()[0]:
        axes[0, -1].legend(loc="upper right", fontsize=8, framealpha=0.85)
    axes[0, 0].set_ylabel(style.label("err_l"))
    if title:
        fig.suptitle(title)
    return style.save(fig, stem)


def pixel_locking(table, stem: Path, bins: int = 10) -> list[str]:
    """Mean error per bin of the truth's fractional pixel position, per method and axis."""
    plt = style.plt()
    ok, meth = has_result(table), _col(table, "method", object)
    colors = style.method_colors(meth)
    edges = np.linspace(-0.5, 0.5, bins + 1)
    centers = 0.5 * (edges[1:] + edges[:-1])
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.6), constrained_layout=True, sharey=True)
    for ax, axis in zip(axes, "sl"):
        truth, err = _col(table, f"truth_{axis}"), _col(table, f"err_{axis}")
        frac = truth - np.round(truth)
        for m in sorted(colors):
            s = ok & (meth == m)
            idx = np.clip(np.digitize(frac[s], edges) - 1, 0, bins - 1)
            mean = [np.mean(err[s][idx == b]) if np.any(idx == b) else np.nan for b in range(bins)]
            ax.plot(centers, mean, "-o", ms=4, color=colors[m], label=m)
        ax.axhline(0, color="0.5", lw=0.5)
        name = "sample" if axis == "s" else "line"
        ax.set(xlabel=f"fractional part of the true {name} (px)", ylabel=f"mean Δ{name} (px)")
        ax.legend()
    return style.save(fig, stem)


#: no-result reasons: greys with hatches, so no reason is ever drawn in a method's (Okabe–Ito) colour
REASON_GREYS = ("#4d4d4d", "#8c8c8c", "#bdbdbd", "#e0e0e0")
REASON_HATCHES = ("", "//", "..", "xx", "\\\\", "++")


def reason_style(j: int) -> tuple[str, str]:
    """(face colour, hatch) of the j-th reason: 4 greys × 6 hatches before one repeats."""
    return REASON_GREYS[j % len(REASON_GREYS)], REASON_HATCHES[(j // len(REASON_GREYS)) % len(REASON_HATCHES)]


def reasons(rows: list[dict], stem: Path) -> list[str]:
    """Stacked share of rows per reason (``ok`` left out), per method; rows from
    :func:`renderlab.report.landmark_stats.reason_counts`. Bars in greys with hatches (:func:`reason_style`); the
    method names under the bars carry the methods' colours."""
    plt = style.plt()
    methods = sorted({r["method"] for r in rows})
    colors = style.method_colors(methods)
    why = sorted({r["reason"] for r in rows if r["reason"] != "ok"})
    fig, ax = plt.subplots(figsize=(2.2 + 1.3 * len(methods), 3.4), constrained_layout=True)
    bottom = np.zeros(len(methods))
    for j, r in enumerate(why):
        share = np.array([sum(x["share"] for x in rows if x["method"] == m and x["reason"] == r) for m in methods])
        face, hatch = reason_style(j)
        ax.bar(methods, 100 * share, bottom=100 * bottom, color=face, hatch=hatch, edgecolor="k", lw=0.5,
               label=r.replace("_", " "))
        bottom += share
    for tick, m in zip(ax.get_xticklabels(), methods):
        tick.set_color(colors[m])
        tick.set_fontweight("bold")
    ax.set(ylabel="rows without a result (%)", ylim=(0, max(1.0, 100 * float(bottom.max()) * 1.1)))
    if why:
        ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    return style.save(fig, stem)


def breakdowns(rows: list[dict], stem: Path) -> tuple[list[str], list[str]]:
    """Bias and robust σ per bin of each covariate with ≥ 2 bins; returns (files, covariates left out)."""
    plt = style.plt()
    by_all = sorted({r["by"] for r in rows})
    by = [b for b in by_all if len({r["bin"] for r in rows if r["by"] == b}) >= 2]
    left_out = [b for b in by_all if b not in by]
    if not by:
        return [], left_out
    colors = style.method_colors({r["method"] for r in rows})
    fig, axes = plt.subplots(2, len(by), figsize=(3.3 * len(by) + 0.6, 5.8), squeeze=False, constrained_layout=True)
    for j, col in enumerate(by):
        for m in sorted(colors):
            for axis, ls in (("s", "-"), ("l", "--")):
                rr = sorted((r for r in rows if r["by"] == col and r["method"] == m and r["axis"] == axis),
                            key=lambda r: r["center"])
                if not rr:
                    continue
                x = [r["center"] for r in rr]
                axes[0, j].errorbar(x, [r["bias_px"] for r in rr],
                                    yerr=[[max(r["bias_px"] - r["bias_px_lo"], 0) for r in rr],
                                          [max(r["bias_px_hi"] - r["bias_px"], 0) for r in rr]],
                                    fmt=ls + "o", ms=3, capsize=2, color=colors[m], label=f"{m}, {axis}")
                axes[1, j].plot(x, [r["robust_sigma_px"] for r in rr], ls + "o", ms=3, color=colors[m],
                                label=f"{m}, {axis}")
        axes[0, j].axhline(0, color="0.5", lw=0.5)
        axes[0, j].set(ylabel="bias (px)")
        axes[1, j].set(xlabel=style.label(col), ylabel="robust σ (px)")
        axes[0, j].legend(fontsize=7)
    return style.save(fig, stem), left_out
