"""The unknown-satellite section of ``renderlab report``: score tables, run flags as a rate with "k of N runs",
Figs 5-7 and 13-14 (:mod:`.figures`), the explanation of a large stage-2 attitude error from the tables, and where
the folder has the ``inertia_observability`` table (:mod:`.observability`; eq. 7, doi:10.1155/2018/9731512) the
Cramér–Rao σ of the inertia ratios against arc length as a figure, a table and a CSV (docs/unknown_satellite.md)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from renderlab.report import style
from renderlab.report.campaign_report import render_blocks, write_csv
from renderlab.report.html_table import table as html_table
from renderlab.studies.unknown_satellite.figures import SCORES, campaign_figures, column, same_pairs, score_summary

__all__ = ["study_section", "attitude_note", "observability_blocks"]

TITLE = "Unknown satellite: scores and figures (Ivanov et al. Figs 5-7, 13-14)"
GROUPS = {"g": "Gauge-free scores (independent of the principal axes)",
          "b": "Body-frame scores (principal axes)", "d": "Stage-1 diagnostics"}
COLUMNS = [("label", "score"), ("unit", "unit"), ("median", "median"), ("p10", "10th percentile"),
           ("p90", "90th percentile"), ("mean", "mean"), ("std", "std"), ("runs", "runs")]
LARGE_ATTITUDE_DEG = 5.0


def attitude_note(scores) -> str:
    """A sentence on a large stage-2 attitude error (median over runs above :data:`LARGE_ATTITUDE_DEG`), from the
    scores: how closely it follows the stage-1 epoch attitude error, how many runs came out relabelled, and the
    Cramér–Rao σ of the inertia ratios that fix the principal axes. Empty when the error is small."""
    names = scores.column_names
    al = "stage2_att_rms_aligned_deg" in names
    col = "stage2_att_rms_aligned_deg" if al else "stage2_att_rms_deg"
    if col not in names:
        return ""
    att = column(scores, col)
    med = float(np.nanmedian(att))
    if not med > LARGE_ATTITUDE_DEG:
        return ""
    n = len(att)
    text = (f"The stage-2 attitude error (median {med:.1f}° over runs{', axes relabelled' if al else ''}) is the error "
            "of the estimated principal axes, not of the pose tracking: the body frame is the principal-axes frame of "
            "the stage-1 inertia estimate")
    att0 = "att0_err_aligned_deg" if al else "att0_err_deg"
    if att0 in names:
        text += (f", and the stage-2 error follows the stage-1 epoch attitude error (median difference "
                 f"{float(np.nanmedian(np.abs(att - column(scores, att0)))):.1f}°)")
    text += ". "
    if "axes_relabelled" in names:
        k = int(np.sum(column(scores, "axes_relabelled", bool)))
        text += (f"Which principal axis is called 1, 2 or 3 (and its sign) is a discrete gauge: {k} of {n} runs came "
                 "out relabelled, and the scores “axes relabelled to truth” undo that. ")
    if {"ratio_sigma_1", "ratio_sigma_2"} <= set(names):
        s1, s2 = (float(np.nanmedian(column(scores, c))) for c in ("ratio_sigma_1", "ratio_sigma_2"))
        if max(s1, s2) > 0.1:
            text += ("What remains is the orientation of the principal axes in the body, which the inertia ratios fix, "
                     f"and they are not observable on this arc (Cramér–Rao σ of I1/I3 and I2/I3: median {s1:.2f} and "
                     f"{s2:.2f}; they become observable with a longer arc, "
                     "<code>results/unknown_satellite/long_arc_120s</code>). ")
        else:
            text += (f"The inertia ratios are well determined here (Cramér–Rao σ median {s1:.3f}, {s2:.3f}), so the "
                     "remaining error is not explained by them; see the run flags. ")
    return text + "The gauge-free scores (points and ω in LVLH, velocity) do not depend on it."


def conclusion(rows: list[dict]) -> str:
    """One sentence from the score medians, against the paper's figures and the Cramér–Rao σ of the same runs."""
    med = {r["score"]: r.get("median") for r in rows}
    parts = []
    if med.get("point_lvlh_err_rms_cm") is not None:
        p, c = med["point_lvlh_err_rms_cm"], med.get("point_lvlh_crlb_rms_cm")
        parts.append(f"reference points {p:.3g} cm RMS in LVLH (paper: 3 cm"
                     + (f"; their CRLB σ here {c:.3g} cm)" if c is not None else ")"))
    if med.get("v0_err_cm_s") is not None:
        parts.append(f"initial velocity {med['v0_err_cm_s']:.3g} cm/s (paper ≈ 1 cm/s)")
    if med.get("w0_norm_err_deg_s") is not None:
        crlb = med.get("w0_norm_crlb_deg_s")
        parts.append(f"‖ω0‖ error {med['w0_norm_err_deg_s']:+.3g} deg/s"
                     + (f" (CRLB σ {crlb:.2g} deg/s)" if crlb is not None else ""))
    s1, s2 = med.get("ratio_sigma_1"), med.get("ratio_sigma_2")
    if s1 is not None and s2 is not None:
        parts.append(f"inertia ratios {'not ' if max(s1, s2) > 0.1 else ''}determined on this arc (CRLB σ of I1/I3 "
                     f"and I2/I3 {s1:.2g} and {s2:.2g})")
    return ("Conclusion (medians over runs): " + "; ".join(parts) + ".") if parts else ""


def _score_tables(rows: list[dict], same: set[str], n_runs: int) -> list[dict]:
    """h3 + table per group of :data:`SCORES`; a raw score equal to its relabelled twin in every run is left out."""
    by_id = {v[0]: (col, v[4]) for col, v in SCORES.items()}
    skip = {SCORES[c][0] for c in same}
    blocks = []
    for g, head in GROUPS.items():
        sel = [r for r in rows if r["score"] in by_id and by_id[r["score"]][1] == g and r["score"] not in skip]
        if sel:
            blocks += [{"kind": "h3", "text": head},
                       {"kind": "table", "html": html_table(sel, COLUMNS, left=("label", "unit"))}]
        if g == "b" and same:
            blocks.append({"kind": "text", "html": "Shown once, because raw and relabelled are equal in every run (no "
                                                   "run's principal axes came out relabelled): "
                                                   + ", ".join(SCORES[c][1] for c in sorted(same)) + "."})
        elif g == "b" and sel:
            blocks.append({"kind": "text", "html": "Raw and relabelled differ because some runs' principal axes came "
                                                   f"out relabelled (see the run flags; {n_runs} runs)."})
    return blocks


def _flag_table(rows: list[dict]) -> list[dict]:
    flags = [{"flag": r["score"][5:].replace("_", " "),
              "label": r["label"].replace("*_aligned scores", "see the scores “axes relabelled to truth”"),
              "rate": f"{100 * r['rate']:.0f} %", "flagged": f"{r['flagged']} of {r['runs']}"}
             for r in rows if r["score"].startswith("flag_")]
    if not flags:
        return []
    return [{"kind": "h3", "text": "Run flags"},
            {"kind": "table", "html": html_table(flags, [("flag", "flag"), ("label", "meaning"), ("rate", "rate (%)"),
                                                          ("flagged", "runs flagged (count)")],
                                                 left=("flag", "label"))}]


#: σ under which a ratio counts as observable in the figure (a 10 % relative error at ratios ≈ 0.6–0.8)
OBSERVABLE_SIGMA = 0.1
OBS_COLUMNS = [("label", "arc"), ("arc_s", "arc (s)"), ("rotation_deg", "tumble (deg)"), ("range_end_m", "range at end (m)"),
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
            {"kind": "table", "html": html_table(seg, OBS_COLUMNS, left=("label",))},
            {"kind": "links", "files": ["unknown_satellite_inertia_observability.csv"]}]


def study_section(tables: dict, out_dir) -> list[tuple[str, str]]:
    """Report hook: the section (title, HTML) of a campaign's tables (it reports ``stage2`` itself); writes
    ``unknown_satellite_summary.csv`` and the figures into ``out_dir``."""
    if "scores" not in tables:
        return []
    out_dir, scores = Path(out_dir), tables["scores"]
    rows = score_summary(scores)
    write_csv(out_dir / "unknown_satellite_summary.csv", rows)
    n = scores.num_rows
    blocks = [{"kind": "text", "html": f"{n} runs. Paper (Ivanov et al. 2018): reference points 3 cm, velocity ≈1 cm/s, "
                                       "‖ω‖ 4.24 deg/s estimated against a gyro's 4.5 deg/s. Body-frame scores depend on "
                                       "the estimated principal axes; gauge-free ones do not."}]
    if conclusion(rows):
        blocks.append({"kind": "text", "html": conclusion(rows)})
    note = attitude_note(scores)
    if note:
        blocks.append({"kind": "text", "html": note})
    blocks += _score_tables(rows, same_pairs(scores), n) + _flag_table(rows)
    blocks += [{"kind": "figure", "png": f["png"], "svg": f["svg"], "alt": f["name"], "caption": f["caption"]}
               for f in campaign_figures(tables, out_dir)]
    if "inertia_observability" in tables:
        blocks += observability_blocks(tables["inertia_observability"], out_dir)
    blocks.append({"kind": "links", "files": ["unknown_satellite_summary.csv"]})
    body = render_blocks(blocks)
    return [(TITLE, body)]
