"""The report section of one landmark measurement table: Fig. 12, the bias/noise table with cluster-bootstrap
intervals, the no-result reasons, the paired comparison, pixel locking and the breakdowns. The CSVs are
``<table>_{reasons,paired,breakdown}.csv``; the summary rows go to the report's one ``summary.csv``."""

from __future__ import annotations

import html
from pathlib import Path

from renderlab.report import landmark_figures as figs
from renderlab.report import landmark_stats as st
from renderlab.report.conclusions import crlb_note, landmark_conclusions
from renderlab.report.csvio import write_csv
from renderlab.report.html_table import table as html_table
from renderlab.report.style import ci

SUMMARY_COLUMNS = [("method", "method"), ("axis", "axis"), ("n_rows", "rows"), ("n_result", "results"),
                   ("n_clusters", "landmark-frames"), ("bias", "bias (px) [95 % CI]"),
                   ("robust_sigma", "robust σ (px) [95 % CI]"), ("std", "std (px) [95 % CI]"),
                   ("gross", "gross errors (%) [95 % CI]"), ("no_result", "no result (%) [95 % CI]")]
INTERVALS = {("frame", "item"): "percentile cluster bootstrap over landmark-frames (rows of one landmark in one "
                                "frame share terrain, truth image and mapping error across runs; i.i.d. intervals "
                                "would be too narrow)",
             ("run",): "percentile cluster bootstrap over runs (each run renders its own truth; the frames of a run "
                       "share its perturbation draw)"}


def summary_cells(rows: list[dict], gross_px: float) -> list[dict]:
    """Summary rows → display cells (intervals as text, rates in %)."""
    out = []
    for r in rows:
        c = {k: r[k] for k in ("method", "axis", "n_rows", "n_result", "n_clusters")}
        c["bias"] = ci(r["bias_px"], r["bias_px_lo"], r["bias_px_hi"])
        c["robust_sigma"] = ci(r["robust_sigma_px"], r["robust_sigma_px_lo"], r["robust_sigma_px_hi"], signed=False)
        c["std"] = ci(r["std_px"], r["std_px_lo"], r["std_px_hi"], signed=False)
        c["gross"] = ci(100 * r["gross_rate"], 100 * r["gross_rate_lo"], 100 * r["gross_rate_hi"], 1, signed=False)
        c["no_result"] = ci(100 * r["no_result_rate"], 100 * r["no_result_rate_lo"], 100 * r["no_result_rate_hi"], 1,
                            signed=False)
        if "robust_sigma_over_crlb" in r:
            c["crlb"] = r["crlb_rms_px"]
            c["ratio"] = r["robust_sigma_over_crlb"]
        out.append(c)
    return out


def subset_blocks(name: str, table, stage: Path, mask, subset: str, *, gross_px: float, label: str,
                  cluster_keys: tuple = st.DEFAULT_CLUSTERS) -> tuple:
    """Blocks (figure + tables) of one subset of a landmark table, and the CSV rows (summary, reasons, paired)."""
    tag = f"{name}_{subset}"
    summary = st.method_summary(table, mask, gross_px=gross_px, subset=subset, cluster_keys=cluster_keys)
    reasons = st.reason_counts(table, mask, subset=subset)
    paired = st.paired_comparison(table, mask, subset=subset, cluster_keys=cluster_keys)
    why = INTERVALS.get(tuple(cluster_keys), f"percentile cluster bootstrap over {st.cluster_name(cluster_keys)}")
    fig = figs.fig12(table, stage / f"{tag}_fig12", mask)
    cols = list(SUMMARY_COLUMNS)
    if summary and "robust_sigma_over_crlb" in summary[0]:
        cols += [("crlb", "registration CRLB rms (px)"), ("ratio", "robust σ / CRLB")]
    blocks = [{"kind": "h3", "text": label},
              {"kind": "figure", "png": fig[0], "svg": fig[1], "alt": f"Fig. 12 {subset}",
               "caption": "Δsample vs Δline per method (shared axes); × the bias (mean), robust 1σ (solid) and 3σ "
                          "(dashed) ellipses (Gnanadesikan–Kettenring covariance on MAD scales, centred at the "
                          "median); points beyond the axes are drawn on the edge and counted in each panel."},
              {"kind": "table", "html": html_table(summary_cells(summary, gross_px), cols, left=("method",))},
              {"kind": "text", "html": f"Gross error: |err| > {gross_px:g} px on that axis, among results. "
                                       f"Intervals: {why}." + (" " + crlb_note(table) if "crlb" in dict(cols) else "")},
              {"kind": "text", "html": landmark_conclusions(summary, gross_px)}]
    if paired:
        prow = [{"pair": f"{p['method_b']} − {p['method_a']}", "n": p["n_pairs"],
                 "d": ci(p["mean_abs_err_b_minus_a_px"], p["lo"], p["hi"]), "share": 100 * p["share_b_smaller"]}
                for p in paired]
        blocks += [{"kind": "table", "html": html_table(prow, [("pair", "pair B − A"), ("n", "paired rows"),
                                                               ("d", "mean |err_B| − |err_A| (px) [95 % CI]"),
                                                               ("share", "rows where B is closer (%)")],
                                                        left=("pair",))},
                   {"kind": "text", "html": "Paired on the same run, frame and landmark where both methods have a "
                                            "result; |err| is the radial error. Negative: B is closer to the truth."}]
    return blocks, summary, reasons, paired


def landmark_section(name: str, table, stage: Path, *, gross_px: float = 1.0, subsets=None,
                     cluster_keys: tuple = st.DEFAULT_CLUSTERS) -> tuple[dict, dict]:
    """The section of table ``name``; ``subsets`` = [(key, mask, label)] reported after "all rows".
    Returns (section, {csv name: rows})."""
    blocks, csvs = [], {"summary": [], "reasons": [], "paired": []}
    for subset, mask, label in [("all", None, "All rows with a truth")] + list(subsets or []):
        b, s, r, p = subset_blocks(name, table, stage, mask, subset, gross_px=gross_px, label=label,
                                   cluster_keys=cluster_keys)
        blocks += b
        csvs["summary"] += [{"table": name, **x} for x in s]
        csvs["reasons"] += [{"table": name, **x} for x in r]
        csvs["paired"] += [{"table": name, **x} for x in p]
    blocks += [{"kind": "h3", "text": "Why there is no result"}, *_reason_blocks(csvs["reasons"], stage, name)]
    pl = figs.pixel_locking(table, stage / f"{name}_pixel_locking")
    blocks += [{"kind": "h3", "text": "Pixel locking"},
               {"kind": "figure", "png": pl[0], "svg": pl[1], "alt": "pixel locking",
                "caption": "Mean error per bin of the truth's fractional pixel position: the sub-pixel peak step's "
                           "bias (flat at zero for an unbiased step)."}]
    brk = [r for col in st.BREAKDOWNS for r in st.breakdown(table, col, cluster_keys=cluster_keys)]
    files, left_out = figs.breakdowns(brk, stage / f"{name}_breakdowns")
    if files:
        blocks += [{"kind": "h3", "text": "Bias and noise against the geometry"},
                   {"kind": "figure", "png": files[0], "svg": files[1], "alt": "breakdowns",
                    "caption": "Bias with 95 % cluster-bootstrap CI (top) and robust σ (bottom) per quantile bin."}]
    if left_out:
        blocks.append({"kind": "text", "html": "Left out (a single bin: the covariate does not vary here): "
                                               + ", ".join(left_out) + "."})
    csvs["breakdown"] = [{"table": name, **r} for r in brk]
    for key, rows in csvs.items():
        if key != "summary":  # the summary rows (with their table column) are the report's summary.csv, written once
            write_csv(stage / f"{name}_{key}.csv", rows)
    blocks.append({"kind": "links", "files": ["summary.csv"] + [f"{name}_{k}.csv" for k in csvs if k != "summary"]})
    return {"title": section_title(name), "anchor": name, "blocks": blocks}, csvs


def section_title(name: str) -> str:
    """"Landmark measurements" for the usual table name, else the table named after it."""
    return "Landmark measurements" if name == "measurements" else f"Landmark measurements ({name.replace('_', ' ')})"


def _reason_blocks(reason_rows: list[dict], stage: Path, name: str) -> list[dict]:
    """The no-result figure, or one sentence when every row of every method has a result (no empty plot)."""
    rows = [r for r in reason_rows if r["subset"] == "all"]
    if not any(r["reason"] != "ok" for r in rows):
        return [{"kind": "text", "html": "Every row of every method has a result: no reason to show."}]
    rfig = figs.reasons(rows, stage / f"{name}_reasons")
    return [{"kind": "figure", "png": rfig[0], "svg": rfig[1], "alt": "no-result reasons",
             "caption": "Share of rows without a result, by the method's reason (the contract's LandmarkReason); "
                        "reasons are drawn in greys with hatches, never in a method's colour."}]


def landmark_report_section(name: str, table, stage: Path, context) -> tuple[dict, list[dict], str]:
    """The landmark kind's ``report_section`` (:mod:`renderlab.contracts.observable`): :func:`landmark_section` with
    the study's subsets, gross-error threshold and cluster columns (its hooks); the summary rows and the headline."""
    study, scenario = context.study, context.scenario or {}
    subsets = study.subsets(table, scenario) if getattr(study, "subsets", None) else []
    gross = study.gross_error_px(scenario) if getattr(study, "gross_error_px", None) else 1.0
    keys = tuple(getattr(study, "clusters", None) or ("frame", "item"))
    sec, csvs = landmark_section(name, table, stage, gross_px=gross, subsets=subsets, cluster_keys=keys)
    return sec, csvs["summary"], headline(csvs["summary"])


def headline(summary: list[dict]) -> str:
    """One line per method on the last (most specific) subset: bias and robust σ per axis with CIs."""
    if not summary:
        return ""
    subset = summary[-1]["subset"]
    rows = [r for r in summary if r["subset"] == subset]
    parts = []
    for m in sorted({r["method"] for r in rows}):
        s, l = (next(r for r in rows if r["method"] == m and r["axis"] == a) for a in "sl")
        parts.append(f"<b>{html.escape(m)}</b>: bias s {ci(s['bias_px'], s['bias_px_lo'], s['bias_px_hi'])}, "
                     f"l {ci(l['bias_px'], l['bias_px_lo'], l['bias_px_hi'])} px; robust σ "
                     f"{s['robust_sigma_px']:.3f} / {l['robust_sigma_px']:.3f} px; no result "
                     f"{100 * s['no_result_rate']:.1f} %")
    return f"Headline ({html.escape(subset)} rows, 95 % cluster-bootstrap CIs): " + "; ".join(parts) + "."
