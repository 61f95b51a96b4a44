"""The navigation budget's figure (:mod:`.navigation_report`): top, per method the touchdown-proxy rms
3-D position error of each budget term (primary mapping ``altitude``, 95 % paired run-bootstrap intervals) with
the other mappings as markers (the bracket) and PASS/FAIL of the quadrature check over the sum bar; bottom, the
validation: rendered campaign vs geometric all-on (each mapping), rms 3-D and median |δr| with intervals.
The report style of :mod:`renderlab.report.style` (Okabe-Ito colours per method); PNG (SVG with ``--svg``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from renderlab.report import style
from renderlab.studies.retina_vs_spc.budget.navigation import term_order

PRIMARY = "altitude"
MARKERS = {"ground": "v", "pixel": "^"}


def _bars(ax, rows, methods, labels, colors):
    width = 0.8 / max(len(methods), 1)
    x = np.arange(len(labels))
    for j, m in enumerate(methods):
        xs = x - 0.4 + (j + 0.5) * width
        vals, lo, hi = (np.full(len(labels), np.nan) for _ in range(3))
        for i, t in enumerate(labels):
            r = next((r for r in rows if r["mapping"] == PRIMARY and r["method"] == m and r["term"] == t), None)
            if r is not None:
                vals[i], lo[i], hi[i] = r["value"], r["lo"], r["hi"]
        err = np.where(np.isfinite(np.vstack([vals - lo, hi - vals])), np.vstack([vals - lo, hi - vals]), 0.0)
        ax.bar(xs, np.nan_to_num(vals), width, color=colors[m], label=f"{m} ({PRIMARY})",
               yerr=np.clip(err, 0, None), capsize=2, error_kw={"elinewidth": 0.8})
        for mp, mk in MARKERS.items():
            v = [next((r["value"] for r in rows if r["mapping"] == mp and r["method"] == m and r["term"] == t),
                      np.nan) for t in labels]
            ax.plot(xs, v, mk, color="black", ms=3, ls="none", label=f"{mp} mapping" if j == 0 else None)
        chk = next((r for r in rows if r["mapping"] == PRIMARY and r["method"] == m
                    and r["term"] == "sum_over_all_on"), None)
        if chk is not None and "quadrature_sum" in labels:
            i = labels.index("quadrature_sum")
            top = max([np.nan_to_num(hi[i])] + [r["value"] for r in rows if r["method"] == m
                                                 and r["term"] == "quadrature_sum"])
            ax.text(xs[i], top * 1.04, f"{chk['check']} {chk['value']:.2f}", rotation=90,
                    ha="center", va="bottom", fontsize=7)
    ax.axhline(0, color="grey", lw=0.5)
    lo_y, hi_y = ax.get_ylim()
    ax.set_ylim(lo_y, hi_y + 0.3 * (hi_y - lo_y))
    ax.set_xticks(x, [t.replace("_", " ") for t in labels], rotation=30, ha="right")
    ax.set_xlabel("budget term (contribution = signed √(v²(source alone) − v²(all off)))")
    ax.set_ylabel("touchdown rms 3-D position error (m)")
    ax.set_title("navigation budget at the 50 m touchdown proxy (PASS: quadrature sum within 20 % of all on)")
    ax.legend(ncol=3, loc="upper left", fontsize=7)


def _validation(ax, val, methods, colors):
    kinds = list(dict.fromkeys((r["kind"], r["mapping"]) for r in val))
    width = 0.8 / max(len(kinds), 1)
    x = np.arange(len(methods))
    hatch = {"rendered": "", "altitude": "//", "ground": "..", "pixel": "xx"}
    for j, (kind, mp) in enumerate(kinds):
        xs = x - 0.4 + (j + 0.5) * width
        rs = [next((r for r in val if r["method"] == m and r["kind"] == kind and r["mapping"] == mp), None)
              for m in methods]
        v = np.array([r["rms_3d"] if r else np.nan for r in rs])
        err = np.array([[r["rms_3d"] - r["rms_3d_lo"], r["rms_3d_hi"] - r["rms_3d"]] if r else [0, 0] for r in rs]).T
        ax.bar(xs, np.nan_to_num(v), width, color=[colors[m] for m in methods], edgecolor="black", lw=0.5,
               hatch=hatch.get(mp or kind, ""), yerr=np.clip(np.nan_to_num(err), 0, None), capsize=2)
        ax.bar([np.nan], [np.nan], color="white", edgecolor="black", lw=0.5, hatch=hatch.get(mp or kind, ""),
               label="rendered campaign" if kind == "rendered" else f"geometric, {mp} mapping")  # legend swatch
        med = [r["median_norm"] if r else np.nan for r in rs]
        ax.plot(xs, med, "o", color="black", ms=3, ls="none", label="median |δr|" if j == 0 else None)
    ax.set_xticks(x, methods)
    ax.set_xlabel("landmark method (all sources on; colour = method, hatch = source of the error)")
    ax.set_ylabel("touchdown rms 3-D position error (m)")
    ax.set_title("validation: rendered closed-loop campaign vs the geometric model, runs that kept track")
    ax.legend(ncol=3, loc="upper left", fontsize=7)
    lo_y, hi_y = ax.get_ylim()
    ax.set_ylim(lo_y, hi_y + 0.3 * (hi_y - lo_y))


def navigation_figure(terms: list[dict], val: list[dict], stem: Path) -> list[str]:
    """Draw the figure into ``stem``.png (statistic rms_3d); returns the file names."""
    rows = [r for r in terms if r["statistic"] == "rms_3d"]
    methods = list(dict.fromkeys(r["method"] for r in rows))
    labels = [t for t in term_order(rows) if t != "sum_over_all_on"]
    colors = style.method_colors(methods)
    plt = style.plt()
    fig, axes = plt.subplots(2 if val else 1, 1, figsize=(11, 9 if val else 5), squeeze=False)
    _bars(axes[0, 0], rows, methods, labels, colors)
    if val:
        _validation(axes[1, 0], val, [m for m in methods if any(r["method"] == m for r in val)], colors)
    fig.tight_layout()
    return style.save(fig, stem)
