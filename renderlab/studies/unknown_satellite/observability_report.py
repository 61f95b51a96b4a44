"""Report blocks of the ``inertia_observability`` table (:mod:`.observability`; Ivanov et al. 2018, eq. 7,
doi:10.1155/2018/9731512): the Cramér–Rao σ of the inertia ratios against arc length as a figure, a table and
``unknown_satellite_inertia_observability.csv``, from the table alone (how it is written: docs/unknown_satellite.md)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from renderlab.report import style
from renderlab.report.csvio import write_csv
from renderlab.report.html_table import table as html_table

__all__ = ["observability_blocks"]

#: σ under which a ratio counts as observable in the figure (a 10 % relative error at ratios ≈ 0.6–0.8)
OBSERVABLE_SIGMA = 0.1
COLUMNS = [("label", "arc"), ("arc_s", "arc (s)"), ("rotation_deg", "tumble (deg)"), ("range_end_m", "range at end (m)"),
           ("database_points", "points (count)"), ("sigma_ratio_12", "σ(I1/I3) (—)"), ("sigma_ratio_23", "σ(I2/I3) (—)"),
           ("sigma_w0_lvlh_deg_s", "σ(ω0, LVLH) (deg/s)")]


def _figure(rows: list[dict], stem: Path) -> list[str]:
    plt = style.plt()
    from matplotlib.ticker import FuncFormatter

    fig, ax = plt.subplots(1, 2, figsize=(10.5, 4.0), constrained_layout=True)
    groups = [(False, style.OKABE_ITO[0], "default separation"), (True, style.OKABE_ITO[1], "slow separation")]
    for k, (col, name) in enumerate((("sigma_ratio_12", "I1/I3"), ("sigma_ratio_23", "I2/I3"))):
        for slow, color, lab in groups:
            sel = sorted((r for r in rows if r["tracks"] == "segments" and r["frames"] == 100
                          and ("slow" in r["label"]) == slow and np.isfinite(r[col])), key=lambda r: r["arc_s"])
            if sel:
                ax[k].plot([r["arc_s"] for r in sel], [r[col] for r in sel], "o-", color=color,
                           label=f"100 frames, {lab}")
        dense = [r for r in rows if r["tracks"] == "segments" and r["frames"] > 100 and np.isfinite(r[col])]
        if dense:
            ax[k].plot([r["arc_s"] for r in dense], [r[col] for r in dense], "s", color=style.OKABE_ITO[2],
                       mfc="none", label="200 or 400 frames, default separation")
        ax[k].axhline(OBSERVABLE_SIGMA, color="k", ls="--", lw=0.8, label=f"σ = {OBSERVABLE_SIGMA:g}")
        ax[k].set_xscale("log")
        ax[k].set_yscale("log")
        for a in (ax[k].xaxis, ax[k].yaxis):
            a.set_major_formatter(FuncFormatter(lambda x, _: f"{x:g}"))
        ax[k].set(xlabel="arc length (s)", ylabel=f"CRLB σ of {name} (dimensionless)", title=f"({'ab'[k]}) {name}")
        ax[k].legend(fontsize=8)
        ax[k].grid(alpha=0.3, which="both")
    fig.suptitle("Are the inertia ratios observable? Cramér–Rao σ (eq. 7) against arc length, σ_px = 0.3")
    return style.save(fig, stem)


def observability_blocks(table, out_dir: Path) -> list[dict]:
    """h3, text, figure and table blocks of the ``inertia_observability`` table (one track model: ``segments``,
    every contiguous visible run of a knob its own point, as the tracker does)."""
    rows = table.to_pylist()
    write_csv(Path(out_dir) / "unknown_satellite_inertia_observability.csv", rows)
    seg = [r for r in rows if r["tracks"] == "segments"]
    if not seg:
        return [{"kind": "text", "html": "The inertia-observability table has no “segments” rows: left out."}]
    png, svg = _figure(rows, Path(out_dir) / "unknown_satellite_inertia_sigma_vs_arc")
    return [{"kind": "h3", "text": "Inertia ratios: Fisher information against arc length"},
            {"kind": "text", "html": "Stage-1 Jacobian at the truth of the scenario, σ = 0.3 px, range prior 5 cm, a "
                                     "synthetic database of the knobs that are in the image, unoccluded and lit; "
                                     "systematic centroid errors are not in F, so these σ are lower bounds."},
            {"kind": "figure", "png": png, "svg": svg, "alt": "inertia_sigma_vs_arc",
             "caption": "Cramér–Rao σ of the inertia ratios against arc length (log axes)."},
            {"kind": "table", "html": html_table(seg, COLUMNS, left=("label",))},
            {"kind": "links", "files": ["unknown_satellite_inertia_observability.csv"]}]
