"""Image in the loop beside the paper's idealised measurements: the modes of a published image folder compared.

A published image-in-the-loop folder (``python -m renderlab.studies.coastline_ekf.publish_image``) holds, all on
the same orbit, image times, σθ, P0, star tracker and seeds:

* ``coastline_filter`` (+ ``coastline_frames``): the campaign, rendered frames → extraction → matching → LOS → EKF;
* ``geometric_filter``: the same scenario in geometric mode, LOS to the visible database points plus σθ noise,
  exactly what the filter assumes (Straub & Christian's simulation, Section III.B);
* ``variant_<name>_filter`` (+ ``variant_<name>_frames``): the campaign again with one scenario change (the
  README names the ``--set`` of each, e.g. ``no_map_error``: ``coastline.map_error_m = 0``).

:func:`report_sections` writes ``comparison.csv`` (one row per mode: final RMS error and filter σ per RIC axis,
the run-mean error, ANEES per time against its 99 % χ²(6N)/N band, the summed NIS against χ²(N Σ 2m_k); image
modes also the median LOS error of the matched points) and ``comparison.png``, from those tables alone.

References
----------
M. N. Straub and J. A. Christian, "Autonomous Optical Navigation for Earth-Observing Satellites Using
Coastline Matching", West Virginia University, AIAA paper, c. 2015 (Table 1, Figs. 5-9, eq. 18).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from renderlab.report import style
from renderlab.report.csvio import write_csv
from renderlab.report.html_table import table as html_table
from renderlab.studies.coastline_ekf.report_section import _render
from renderlab.studies.coastline_ekf.scoring import nis_total_test, per_time_summary

__all__ = ["is_comparison_table", "modes", "mode_summary", "plot_comparison", "report_sections"]

_POS = (("r", "radial"), ("i", "in-track"), ("c", "cross-track"))


def is_comparison_table(name: str) -> bool:
    """A table shown only in the comparison (not as a section of its own)."""
    return name == "geometric_filter" or (name.startswith("variant_") and name.endswith("_filter"))


def modes(tables: dict) -> list[tuple[str, object, object]]:
    """``[(label, filter table, frames table or None), ...]``: geometric, the campaign, then the variants."""
    out = [("geometric (idealised LOS)", tables["geometric_filter"], None),
           ("image", tables["coastline_filter"], tables.get("coastline_frames"))]
    for name in sorted(n for n in tables if is_comparison_table(n) and n != "geometric_filter"):
        key = name[len("variant_"):-len("_filter")]
        out.append((f"image, {key.replace('_', ' ')}", tables[name], tables.get(f"variant_{key}_frames")))
    return out


def mode_summary(label: str, table, frames=None) -> tuple[dict, object]:
    """One row of ``comparison.csv`` and the per-time summary of one mode's filter table."""
    core = table.drop([c for c in ("campaign", "has_result", "reason") if c in table.column_names])
    s = per_time_summary(core)
    n = int(s["n_runs"].to_numpy()[0])
    row = {"mode": label, "runs": n, "images": int(len(s) - 1), "los_per_image_mean": float(np.mean(s["n_meas"].to_numpy()[1:]))}
    for a, u, scale, unit in (("r", "m", 1, "m"), ("i", "m", 1, "m"), ("c", "m", 1, "m"),
                              ("vr", "mps", 1e3, "mmps"), ("vi", "mps", 1e3, "mmps"), ("vc", "mps", 1e3, "mmps")):
        row[f"final_rms_{a}_{unit}"] = float(s[f"mc_rms_{a}_{u}"].to_numpy()[-1] * scale)
        row[f"final_filter_sig_{a}_{unit}"] = float(s[f"filter_sig_{a}_{u}"].to_numpy()[-1] * scale)
    for a, _ in _POS:
        row[f"final_mean_{a}_m"] = float(s[f"mc_mean_{a}_m"].to_numpy()[-1])
        row[f"final_mean_sem_{a}_m"] = float(np.std(_final(core, f"err_{a}_m"), ddof=1) / np.sqrt(n)) if n > 1 else np.nan
    anees, lo, hi = (s[c].to_numpy() for c in ("anees", "anees_lo", "anees_hi"))
    inside = (anees >= lo) & (anees <= hi)
    row.update(anees_final=float(anees[-1]), anees_lo=float(lo[-1]), anees_hi=float(hi[-1]),
               anees_final_inside_99=bool(inside[-1]), anees_inside_99_fraction=float(np.mean(inside)),
               anees_by_time=" ".join(f"{v:.1f}" for v in anees))       # prior, then one value per image
    nis = nis_total_test(core)
    row.update(nis_total_over_dof=nis["ratio"], nis_total_inside_99=nis["inside"])
    if frames is not None:
        row["los_err_px_median_over_images"] = float(np.nanmedian(frames["los_err_px_median"].to_numpy()))
        row["images_without_match_fraction"] = float(np.mean(frames["n_matched"].to_numpy() == 0))
    return row, s


def _final(table, column: str) -> np.ndarray:
    """``column`` of every run at the last time."""
    t = table["t_s"].to_numpy()
    return table[column].to_numpy()[t == t.max()]


def plot_comparison(summaries: dict, stem: Path) -> list[str]:
    """RMS position error and filter σ per RIC axis, and ANEES with its 99 % band, for every mode (PNG; SVG under ``--svg``)."""
    plt = style.plt()
    fig, axs = plt.subplots(1, 4, figsize=(16, 4.4), constrained_layout=True)
    for j, (mode, s) in enumerate(summaries.items()):
        colour = style.OKABE_ITO[j % len(style.OKABE_ITO)]
        t = s["t_s"].to_numpy() - s["t_s"].to_numpy()[0]
        for ax, (a, name) in zip(axs[:3], _POS):
            ax.plot(t, s[f"mc_rms_{a}_m"].to_numpy(), "-", color=colour, label=f"{mode}: Monte Carlo RMS")
            ax.plot(t, s[f"filter_sig_{a}_m"].to_numpy(), "--", color=colour, label=f"{mode}: filter σ")
            ax.set_ylabel(f"{name} position error (m)")
        anees, lo, hi = (s[c].to_numpy() for c in ("anees", "anees_lo", "anees_hi"))
        if j == 0:
            axs[3].fill_between(t, lo, hi, color="0.8", label=f"99 % χ² band ({int(s['n_runs'][0].as_py())} runs)")
        inside = (anees >= lo) & (anees <= hi)
        axs[3].plot(t, anees, "-", color=colour, lw=1.0)
        axs[3].plot(t[inside], anees[inside], "o", color=colour, ms=4, label=f"{mode}: inside its band")
        if (~inside).any():
            axs[3].plot(t[~inside], anees[~inside], "x", color=colour, ms=7, mew=2, label=f"{mode}: outside its band")
    axs[3].set_ylabel("ANEES (6 dof)")
    for ax in axs:
        ax.set_xlabel("time since the prior (s)")
        ax.grid(alpha=0.3)
    axs[0].legend(fontsize=7)
    axs[3].legend(fontsize=7)
    for ax, (_, name) in zip(axs[:3], _POS):
        ax.set_title(f"{name} position: RMS (solid), filter σ (dashed)")
    axs[3].set_title("ANEES against its 99 % χ² band")
    fig.suptitle("Coastline EKF: idealised LOS (geometric, the paper's simulation) vs rendered images (extraction, "
                 "matching, map error, clouds); same orbit, times, σθ, P0 and seeds")
    return style.save(fig, stem)


def report_sections(tables: dict, stage: Path) -> list[tuple[str, str]]:
    """The comparison section (``comparison.csv``, ``comparison.png``) when ``geometric_filter`` is present."""
    if "geometric_filter" not in tables or "coastline_filter" not in tables:
        return []
    rows, summaries = [], {}
    for label, table, frames in modes(tables):
        row, summaries[label] = mode_summary(label, table, frames)
        rows.append(row)
    write_csv(Path(stage) / "comparison.csv", rows)
    png, svg = plot_comparison(summaries, Path(stage) / "comparison")
    shown = [{**r, "anees_badge": style.badge(r["anees_final_inside_99"]), "nis_badge": style.badge(r["nis_total_inside_99"]),
              "pos": " / ".join(f"{r[f'final_rms_{a}_m']:.0f}" for a, _ in _POS),
              "sig": " / ".join(f"{r[f'final_filter_sig_{a}_m']:.0f}" for a, _ in _POS),
              "band": f"[{r['anees_lo']:.2f}, {r['anees_hi']:.2f}]"} for r in rows]
    cols = [("mode", "mode"), ("los_per_image_mean", "LOS per image (mean)"),
            ("pos", "RMS error R / I / C at the last image (m)"), ("sig", "filter σ R / I / C (m)"),
            ("anees_final", "ANEES at the last image"), ("band", "99 % band"), ("anees_badge", "consistent?"),
            ("anees_inside_99_fraction", "share of times inside"), ("nis_total_over_dof", "total NIS / dof"),
            ("nis_badge", "NIS consistent?")]
    blocks = [{"kind": "text", "html": "All modes share the orbit, image times, σθ, P0, star tracker and seeds; "
                                       "only the measurements differ."},
              {"kind": "table", "html": html_table(shown, cols, left=("mode", "pos", "sig", "band"),
                                                   raw=("anees_badge", "nis_badge"))},
              {"kind": "figure", "png": png, "svg": svg, "alt": "coastline modes compared",
               "caption": "RMS position error and filter σ per RIC axis, and ANEES against its 99 % χ² band "
                          "(crosses: outside the band), for every mode."},
              {"kind": "links", "files": ["comparison.csv"]}]
    return [("Coastline EKF: image in the loop vs idealised measurements", _render(blocks))]
