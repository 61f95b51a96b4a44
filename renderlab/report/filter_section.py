"""The report section of one filter table: errors against time with the filter's ±3σ, and ANEES/ANIS against their
two-sided χ² bands with a pass/fail badge."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from renderlab.campaign import scoring
from renderlab.report import style
from renderlab.report.conclusions import filter_sentence
from renderlab.report.csvio import write_csv
from renderlab.report.html_table import table as html_table


def _col(t, name, dtype=float):
    return np.asarray(t.column(name).to_numpy(zero_copy_only=False), dtype)


def time_unit(t_s: np.ndarray) -> tuple[float, str]:
    """(divisor, unit): hours when the span exceeds 2 h, else seconds (one unit per report)."""
    span = float(np.nanmax(t_s) - np.nanmin(t_s)) if t_s.size else 0.0
    return (3600.0, "h") if span > 7200 else (1.0, "s")


def errors_figure(t, stem: Path) -> list[str]:
    """Every ``err_*`` column against time, each run a thin line, the mean filter ±3σ dashed."""
    plt = style.plt()
    cols = [c for c in t.column_names if c.startswith("err_")]
    fig, axes = plt.subplots(len(cols), 1, figsize=(8, 1.9 * len(cols) + 0.5), squeeze=False, sharex=True,
                             constrained_layout=True)
    runs, ts = _col(t, "run", np.int64), _col(t, "t_s")
    div, unit = time_unit(ts)
    for ax, c in zip(axes[:, 0], cols):
        v = _col(t, c)
        for k, r in enumerate(np.unique(runs)):
            s = runs == r
            ax.plot(ts[s] / div, v[s], lw=0.5, alpha=0.5, color=style.OKABE_ITO[0],
                    label=f"error, {len(np.unique(runs))} runs" if k == 0 else None)
        sig = "sig_" + c[4:]
        if sig in t.column_names:
            uniq = np.unique(ts)
            s3 = np.array([3 * np.nanmean(_col(t, sig)[ts == u]) for u in uniq])
            ax.plot(uniq / div, s3, "--", color="k", lw=1, label="filter ±3σ (run mean)")
            ax.plot(uniq / div, -s3, "--", color="k", lw=1)
        ax.set(ylabel=style.label(c))
        ax.legend(fontsize=8, loc="upper right")
    axes[-1, 0].set(xlabel=f"time ({unit})")
    return style.save(fig, stem)


def filter_section(name: str, t, stage: Path, *, confidence: float = 0.95) -> tuple[dict, list[dict]]:
    """The section of filter table ``name`` and its summary rows."""
    rows = scoring.score_filter(t, confidence=confidence)
    write_csv(stage / f"{name}_filter_summary.csv", rows)
    fig = errors_figure(t, stage / f"{name}_errors")
    err_rows = [r for r in rows if r["quantity"].startswith("err_")]
    cons = [r for r in rows if r["quantity"] in ("anees", "anis")]
    for r in cons:
        inside = r["chi2_lo"] <= r["mean"] <= r["chi2_hi"]
        r["badge"] = style.badge(inside, f"{100 * r['fraction_inside']:.0f} % of times inside")
    blocks = [{"kind": "figure", "png": fig[0], "svg": fig[1], "alt": f"{name} errors",
               "caption": "Estimation errors against time, every run; dashed: the filter's own ±3σ."},
              {"kind": "table", "html": html_table([{**r, "quantity": style.label(r["quantity"])} for r in err_rows],
                                                   [("quantity", "error"), ("n", "samples"), ("mean", "mean"),
                                                    ("std", "std"), ("rms", "rms"), ("median", "median")],
                                                   left=("quantity",))}]
    if cons:
        blocks.append({"kind": "table", "html": html_table(
            [{**r, "quantity": r["quantity"].upper()} for r in cons],
            [("quantity", "statistic"), ("mean", "value"), ("chi2_lo", f"χ² band low ({confidence:.0%})"),
             ("chi2_hi", f"χ² band high ({confidence:.0%})"), ("badge", "consistent?")], left=("quantity",),
            raw=("badge",))})
        blocks.append({"kind": "text", "html": "ANEES/ANIS: mean NEES/NIS over all runs and times; the band is the "
                                               "two-sided χ² interval for N runs × d dof, divided by N."})

    sentence = filter_sentence(rows)
    if sentence:
        blocks.append({"kind": "text", "html": sentence})
    return {"title": f"Filter: {name}", "anchor": name, "blocks": blocks}, rows


def filter_report_section(name: str, table, stage: Path, context) -> tuple[dict, list[dict], str]:
    """The filter kind's ``report_section`` (:mod:`renderlab.contracts.observable`): :func:`filter_section`; its rows
    stay in ``<name>_filter_summary.csv`` (none go to the report's ``summary.csv``), no headline."""
    sec, _ = filter_section(name, table, stage, confidence=context.confidence)
    return sec, [], ""
