"""The figure of a one-at-a-time error budget (:mod:`renderlab.stats.oat_budget`): per statistic a bar chart of
the budget terms per method, with 95 % joint cluster-bootstrap intervals, the median registration CRLB and 2 × CRLB as lines, and PASS/FAIL
of the quadrature check (sum within 20 % of all on) over each method's sum bar. The report style of
:mod:`renderlab.report.style` (Okabe-Ito colours per method); PNG (SVG with ``--svg``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from renderlab.report import style

PANELS = (("robust_sigma", "robust σ of the error"), ("bias_rms", "per-landmark bias rms"),
          ("noise_sd", "per-landmark noise sd"))


def budget_figure(summary: list[dict], terms: list[dict], stem: Path, terms_order: tuple[str, ...]) -> list[str]:
    """Draw the figure into ``stem``.png (subset all, both axes pooled; the bars in ``terms_order``); returns the file
    names."""
    rows = [r for r in terms if r["subset"] == "all" and r["axis"] == "both"]
    methods = list(dict.fromkeys(r["method"] for r in rows))
    labels = [t for t in terms_order if any(r["term"] == t for r in rows)]
    colors = style.method_colors(methods)
    crlb = np.nanmedian([r["crlb"] for r in summary if r["subset"] == "all" and r["axis"] == "both"
                         and r["config"] == "all_off"])
    plt = style.plt()
    fig, axes = plt.subplots(len(PANELS), 1, figsize=(11, 10), sharex=True)
    width = 0.8 / max(len(methods), 1)
    x = np.arange(len(labels))
    for ax, (stat, title) in zip(axes, PANELS):
        for j, m in enumerate(methods):
            vals, lo, hi = (np.full(len(labels), np.nan) for _ in range(3))
            for i, t in enumerate(labels):
                r = next((r for r in rows if r["method"] == m and r["term"] == t and r["statistic"] == stat), None)
                if r is not None:
                    vals[i], lo[i], hi[i] = r["value"], r["lo"], r["hi"]
            xs = x - 0.4 + (j + 0.5) * width
            err = np.vstack([np.clip(vals - lo, 0, None), np.clip(hi - vals, 0, None)])
            err = np.where(np.isfinite(err), err, 0.0)
            ax.bar(xs, np.nan_to_num(vals), width, color=colors[m], label=m, yerr=err, capsize=2,
                   error_kw={"elinewidth": 0.8})
            chk = next((r for r in rows if r["method"] == m and r["term"] == "sum_over_all_on"
                        and r["statistic"] == stat), None)
            if chk is not None and chk["check"] and "quadrature_sum" in labels:
                i = labels.index("quadrature_sum")
                ax.text(xs[i], np.nan_to_num(hi[i]) * 1.02 + 1e-4, f"{chk['check']} {chk['value']:.2f}",
                        rotation=90, ha="center", va="bottom", fontsize=7)
        ax.axhline(crlb, color="black", ls="--", lw=1, label=f"median CRLB {crlb:.4f} px")
        ax.axhline(2 * crlb, color="black", ls=":", lw=1, label="2 × CRLB")
        ax.axhline(0, color="grey", lw=0.5)
        lo_y, hi_y = ax.get_ylim()
        ax.set_ylim(lo_y, hi_y + 0.3 * (hi_y - lo_y))  # room for the PASS/FAIL marks
        ax.set_ylabel(f"{title} (px)")
        ax.set_title(f"{title}: all off, each source's contribution, quadrature sum (PASS: within 20 % of all on)")
    axes[0].legend(ncol=3, loc="upper left")
    axes[-1].set_xticks(x, [t.replace("_", " ") for t in labels], rotation=30, ha="right")
    axes[-1].set_xlabel("budget term (contribution = signed √(v²(source alone) − v²(all off)), px)")
    fig.tight_layout()
    return style.save(fig, stem)
