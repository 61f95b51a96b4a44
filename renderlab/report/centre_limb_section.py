"""The centre/limb kind's report section (:data:`renderlab.contracts.centre_limb.CENTRE_LIMB` ``report_section``).

From one ``centre_limb`` table alone (:mod:`renderlab.stats.centre_limb`): two figures — the centre bias in apparent
radii and the relative range error per grid cell against the phase angle, one panel per law; each method's ANEES
against its χ² band — a table per method of bias, noise, line-of-sight and range errors with cluster-bootstrap
intervals (cluster = grid cell), the ANEES with PASS/FAIL, the no-result reasons, and one conclusion sentence per
method. CSV: ``<name>_summary.csv`` (the summary rows; none go to the report's ``summary.csv``, which would copy it)
and ``<name>_cells.csv`` (per method and cell).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from renderlab.report import style
from renderlab.report.csvio import write_csv
from renderlab.report.html_table import table as html_table
from renderlab.stats.centre_limb import cell_table, derived, score_table


def _panels(cells: list[dict], laws: list[str]):
    plt = style.plt()
    fig, axes = plt.subplots(2, len(laws), figsize=(4.2 * len(laws), 6.2), squeeze=False, constrained_layout=True)
    return plt, fig, axes


def bias_figure(cells: list[dict], stem: Path) -> list[str | None]:
    """|centre bias| / apparent radius (top) and relative range bias (bottom) per cell against phase, per law;
    the mean over the ranges of the grid at each phase, one line per method."""
    laws = sorted({c["law"] for c in cells}) or [""]
    methods = sorted({c["method"] for c in cells})
    colors = style.method_colors(methods)
    _, fig, axes = _panels(cells, laws)
    for j, law in enumerate(laws):
        for m in methods:
            mine = [c for c in cells if c["method"] == m and c["law"] == law]
            phases = sorted({round(c["phase_deg"]) for c in mine})
            top, bottom = [], []
            for p in phases:
                at = [c for c in mine if round(c["phase_deg"]) == p]
                top.append(np.nanmean([math.hypot(c["bias_s_px"], c["bias_l_px"]) / c["radius_px"] for c in at])
                           if any(math.isfinite(c["bias_s_px"]) for c in at) else np.nan)
                bottom.append(np.nanmean([c["bias_range_rel"] for c in at])
                              if any(math.isfinite(c["bias_range_rel"]) for c in at) else np.nan)
            axes[0, j].semilogy(phases, top, "o-", color=colors[m], label=m, ms=3)
            if np.isfinite(bottom).any():
                axes[1, j].plot(phases, 100 * np.asarray(bottom), "o-", color=colors[m], label=m, ms=3)
        axes[0, j].set(title=f"law: {law}", xlabel="phase angle (deg)",
                       ylabel="|centre bias| / apparent radius (—)")
        axes[1, j].axhline(0.0, color="k", lw=0.5)
        axes[1, j].set_yscale("symlog", linthresh=0.1)
        axes[1, j].set(xlabel="phase angle (deg)", ylabel="range bias (%, linear within ±0.1)")
        axes[0, j].legend(fontsize=7, loc="best")
        axes[1, j].legend(fontsize=7, loc="best")
    return style.save(fig, stem)


def nees_figure(rows: list[dict], stem: Path) -> list[str | None]:
    """Each method's ANEES (centre, 2 dof; position, 3 dof) with its interval and χ² band, and its median NEES
    against the χ² median, log scale."""
    plt = style.plt()
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.6), constrained_layout=True)
    med = {(r["method"], r["quantity"]): r["estimate"] for r in rows if r["group"] == "all"}
    for ax, q, chi2_median in zip(axes, ("anees_centre", "anees_position"), (1.386, 2.366)):
        mine = [r for r in rows if r["quantity"] == q and r["group"] == "all" and r["n"] > 0]
        ax.axhline(chi2_median, color="0.5", ls=":", lw=1, label="χ² median")
        for k, r in enumerate(mine):
            ax.plot([k + 0.15], [med[(r["method"], "median_nees_" + q[6:])]], "x", color="k", label="median NEES")
            ax.errorbar([k], [r["estimate"]], yerr=[[max(r["estimate"] - r["lo"], 0)], [max(r["hi"] - r["estimate"],
                        0)]], fmt="o", color="C0" if r["inside"] else "C3",
                        label=("ANEES, PASS" if r["inside"] else "ANEES, FAIL"))
            ax.plot([k - 0.3, k + 0.3], [r["band_lo"]] * 2, "k-", lw=1, label="χ² band (95 %)")
            ax.plot([k - 0.3, k + 0.3], [r["band_hi"]] * 2, "k-", lw=1)
        ax.set_yscale("log")
        ax.set_xticks(range(len(mine)), [r["method"] for r in mine], rotation=30, ha="right", fontsize=8)
        ax.set(ylabel=f"{'centre' if q == 'anees_centre' else 'position'} NEES: mean (ANEES), median (—)")
        h, lab = ax.get_legend_handles_labels()
        keep = dict(zip(lab, h))
        ax.legend(keep.values(), keep.keys(), fontsize=7)
    return style.save(fig, stem)


def _cells_with_radius(table, d) -> list[dict]:
    cells = cell_table(d)
    rad = np.asarray(table.column("true_radius_px").to_numpy(zero_copy_only=False), float)
    for c in cells:
        s = (d["method"] == c["method"]) & (d["cell"] == c["cell"])
        c["radius_px"] = float(np.nanmean(rad[s]))
    return cells


def sentence(method: str, rows: list[dict], cells: list[dict]) -> str:
    """One conclusion sentence for a method from its summary rows (group ``all``) and cells."""
    q = {r["quantity"]: r for r in rows if r["method"] == method and r["group"] == "all"}
    mine = [c for c in cells if c["method"] == method and math.isfinite(c["bias_s_px"])]
    parts = [f"<b>{method}</b>: results on {100 * q['result_rate']['estimate']:.1f} % of the images"]
    if mine:
        worst = max(mine, key=lambda c: math.hypot(c["bias_s_px"], c["bias_l_px"]) / c["radius_px"])
        parts.append(f"centre bias up to {math.hypot(worst['bias_s_px'], worst['bias_l_px']):.2f} px "
                     f"({math.hypot(worst['bias_s_px'], worst['bias_l_px']) / worst['radius_px']:.3f} radii, "
                     f"{worst['law']}, phase {worst['phase_deg']:.0f}°), within-cell noise "
                     f"{q['noise_s']['estimate']:.2f}/{q['noise_l']['estimate']:.2f} px (s/l)")
    rr = q.get("bias_range_rel")
    if rr and math.isfinite(rr["estimate"]):
        parts.append(f"range bias {100 * rr['estimate']:+.2f} % [{100 * rr['lo']:+.2f}, {100 * rr['hi']:+.2f}]")
    a = q.get("anees_centre")
    if a and a["n"]:
        word = "consistent" if a["inside"] else ("over-confident" if a["estimate"] > a["band_hi"] else "conservative")
        parts.append(f"its own centre covariance is {word} (ANEES {a['estimate']:.3g}, band "
                     f"[{a['band_lo']:.3g}, {a['band_hi']:.3g}]; median NEES {q['median_nees_centre']['estimate']:.3g}"
                     f" against χ²₂'s 1.39)")
    return "; ".join(parts) + "."


SUMMARY_COLUMNS = [("method", "method"), ("bias_s", "bias s (px)"), ("bias_l", "bias l (px)"),
                   ("noise_s", "noise s (px)"), ("noise_l", "noise l (px)"), ("los_rms_urad", "LOS RMS (µrad)"),
                   ("bias_range_rel", "range bias (%)"), ("noise_range_rel", "range noise (%)"),
                   ("result_rate", "with result (%)")]


def _summary_html(rows: list[dict], group: str) -> str:
    out = []
    for m in sorted({r["method"] for r in rows}):
        q = {r["quantity"]: r for r in rows if r["method"] == m and r["group"] == group}
        if not q:
            continue
        line = {"method": m}
        for k, _ in SUMMARY_COLUMNS[1:]:
            r = q[k]
            scale = 100.0 if k in ("bias_range_rel", "noise_range_rel", "result_rate") else 1.0
            line[k] = style.ci(scale * r["estimate"], scale * r["lo"], scale * r["hi"], digits=3,
                               signed=k.startswith("bias"))
        out.append(line)
    return html_table(out, SUMMARY_COLUMNS, left=("method",))


def _g(v: float) -> str:
    return f"{v:.3g}" if math.isfinite(v) else "–"


def _nees_html(rows: list[dict]) -> str:
    med = {(r["method"], r["quantity"]): r for r in rows if r["group"] == "all"}
    out = []
    for r in rows:
        if r["group"] == "all" and r["quantity"].startswith("anees") and r["n"] > 0:
            m = med[(r["method"], "median_nees_" + r["quantity"][6:])]
            out.append({**r, "ci": f"{_g(r['estimate'])} [{_g(r['lo'])}, {_g(r['hi'])}]",
                        "median": f"{_g(m['estimate'])} [{_g(m['lo'])}, {_g(m['hi'])}]",
                        "band": f"[{r['band_lo']:.3g}, {r['band_hi']:.3g}]", "badge": style.badge(r["inside"])})
    return html_table(out, [("method", "method"), ("what", "statistic"), ("n", "images"),
                            ("ci", "ANEES [95 % interval]"), ("band", "χ² band (95 %)"), ("badge", "PASS/FAIL"),
                            ("median", "median NEES [95 %] (χ²: 1.39 / 2.37)")],
                      left=("method", "what"), raw=("badge",))


def _reasons_html(d: dict) -> str:
    reasons = sorted(set(d["reason"]))
    out = []
    for m in sorted(set(d["method"])):
        s = d["method"] == m
        out.append({"method": m, **{r: int(np.sum(d["reason"][s] == r)) for r in reasons}})
    return html_table(out, [("method", "method")] + [(r, f"{r} (images)") for r in reasons], left=("method",))


def report_section(name: str, table, out_dir: Path, context) -> tuple[dict, list[dict], str]:
    """The kind's ``report_section`` (module docstring): (section, no summary rows — they are in
    ``<name>_summary.csv`` —, headline)."""
    confidence = getattr(context, "confidence", 0.95)
    rows = score_table(table, confidence=confidence)
    d = derived(table)
    cells = _cells_with_radius(table, d)
    write_csv(Path(out_dir) / f"{name}_summary.csv", rows)
    write_csv(Path(out_dir) / f"{name}_cells.csv", cells)
    fb, fn = bias_figure(cells, Path(out_dir) / f"{name}_bias"), nees_figure(rows, Path(out_dir) / f"{name}_nees")
    n_cells = len(np.unique(d["cell"]))
    n_draws = table.num_rows // max(n_cells * len(set(d["method"])), 1)  # images per cell, every method on each
    ci_note = (f"Intervals: {confidence:.0%} percentile cluster bootstrap over the {n_cells} grid cells (the images "
               "of a cell share its geometry and bias; its draws are independent). Noise: RMS about each cell's "
               "mean. LOS: the angle of the centre error at the focal length.")
    blocks = [
        {"kind": "figure", "png": fb[0], "svg": fb[1], "alt": "centre and range bias against phase",
         "caption": "Top: |mean centre error| of each cell over its apparent radius; bottom: mean relative range "
                    "error (methods that give a range); both averaged over the grid's ranges at each phase angle."},
        {"kind": "h3", "text": "Bias and noise per method (all cells)"},
        {"kind": "table", "html": _summary_html(rows, "all")},
        {"kind": "text", "html": ci_note},
    ]
    for law in sorted(set(d["law"]) - {""}):
        blocks += [{"kind": "h3", "text": f"Bias and noise per method, law {law}"},
                   {"kind": "table", "html": _summary_html(rows, str(law))}]
    blocks += [
        {"kind": "h3", "text": "Consistency of each method's own covariance"},
        {"kind": "figure", "png": fn[0], "svg": fn[1], "alt": "ANEES per method",
         "caption": "ANEES (mean NEES of the method's own covariance) with its cluster-bootstrap interval; black: "
                    "the two-sided 95 % χ² band of N independent values (2 dof centre, 3 dof position); ×: the "
                    "median NEES, dotted: the χ² median it should match."},
        {"kind": "table", "html": _nees_html(rows)},
        {"kind": "h3", "text": "No-result reasons"},
        {"kind": "table", "html": _reasons_html(d)},
        {"kind": "h3", "text": "Conclusions"},
    ]
    blocks += [{"kind": "text", "html": sentence(m, rows, cells)} for m in sorted(set(d["method"]))]
    blocks.append({"kind": "links", "files": [f"{name}_summary.csv", f"{name}_cells.csv"]})
    best = min((r for r in rows if r["group"] == "all" and r["quantity"] == "los_rms_urad"
                and math.isfinite(r["estimate"])), key=lambda r: r["estimate"], default=None)
    head = (f"{name}: {len(set(d['method']))} centre/limb methods on {n_cells} cells × {n_draws} draws; smallest "
            f"RMS line-of-sight error: {best['method']} ({best['estimate']:.0f} µrad)" if best else "")
    return {"title": f"Centre/limb: {name}", "anchor": name, "blocks": blocks}, [], head
