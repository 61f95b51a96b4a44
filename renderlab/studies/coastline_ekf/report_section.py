"""The coastline-EKF sections of ``renderlab report``: Figs. 5-9, ANEES/ANIS with their 99 % χ² bands (the NIS of an
image has 2m dof, so the study reports its filter tables itself: ``own_tables``), PCRB when published, pass/fail
badges and the study's known reason for a value outside its band; and the comparison of the modes of a published
image folder (``coastline_filter``, ``geometric_filter``, ``variant_<name>_filter``: ``comparison.csv`` and
``comparison.png``; docs/coastline_ekf.md).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from renderlab.report import style
from renderlab.report.campaign_report import render_blocks
from renderlab.report.csvio import write_csv
from renderlab.report.html_table import table as html_table
from renderlab.studies.coastline_ekf.figures import plot_consistency, plot_errors, time_unit
from renderlab.studies.coastline_ekf.scoring import nis_total_test, per_time_summary, steady_state

__all__ = ["is_coastline_table", "coastline_section", "summary_blocks", "is_comparison_table", "modes", "mode_summary",
           "plot_comparison", "comparison_sections"]

_ROWS = [("r", "m", "radial position", 1, "m"), ("i", "m", "in-track position", 1, "m"),
         ("c", "m", "cross-track position", 1, "m"), ("vr", "mps", "radial velocity", 1e3, "mm/s"),
         ("vi", "mps", "in-track velocity", 1e3, "mm/s"), ("vc", "mps", "cross-track velocity", 1e3, "mm/s")]


MAP_ERROR = ("The study's own README (<code>results/coastline_ekf/image_in_the_loop/README.md</code>) traces an "
             "ANEES above its band in the image mode to the onboard map error that the filter does not model: the "
             "database error is smooth, so the points of one image are displaced nearly alike; that common error "
             "looks like a position error, and the filter's R (eq. 18, independent LOS) takes it as information, "
             "which makes the filter inconsistent. With the error modelled in R as a shared per-image LOS rotation "
             "(<code>coastline.map_error_in_filter = true</code>) ANEES stays inside its band at every time; with no "
             "map error it ends below its band (the σθ the filter assumes then exceeds the measured image error).")
GEOMETRIC = ("Known causes of an ANEES above its band in the geometric mode are what the filter does not model: "
             "a J2 truth (<code>trajectory.j2</code>) against the two-body filter with Q = 0, or, with few points "
             "per image and a large σθ, km-level in-track errors that bend the EKF's linearisation about its own "
             "estimate (<code>results/coastline_ekf/README.md</code>, sensitivity section).")


def is_coastline_table(table) -> bool:
    """A coastline filter table: the filter columns plus the per-image LOS count ``n_meas``."""
    return {"run", "t_s", "nees", "nis", "n_meas"} <= set(table.column_names)


def _steady_table(ss: dict) -> str:
    """Monte Carlo / filter / PCRB 3σ per RIC axis, with a unit column (PCRB column only when given)."""
    rows, pcrb = [], "pcrb_3sig_r_m" in ss
    for a, u, label, scale, unit in _ROWS:
        mc, fl = ss[f"mc_3sig_{a}_{u}"] * scale, ss[f"filter_3sig_{a}_{u}"] * scale
        rows.append({"axis": label, "unit": unit, "mc": mc, "filter": fl, "ratio": mc / fl if fl else float("nan"),
                     "pcrb": ss.get(f"pcrb_3sig_{a}_{u}", float("nan")) * scale})
    cols = [("axis", "error (RIC of the true orbit)"), ("unit", "unit"), ("mc", "Monte Carlo 3σ"),
            ("filter", "filter 3σ")] + ([("pcrb", "PCRB 3σ")] if pcrb else []) + [("ratio", "Monte Carlo / filter")]
    return html_table(rows, cols, left=("axis", "unit"))


def _consistency(summary, nis: dict, tname: str, div: float) -> tuple[list[dict], dict]:
    """Rows of the consistency table (ANEES at the final time, total NIS per dof) and the verdicts."""
    anees, lo, hi = (summary[c].to_numpy() for c in ("anees", "anees_lo", "anees_hi"))
    img = summary["n_meas"].to_numpy() > 0
    anis, alo, ahi = (summary[c].to_numpy()[img] for c in ("anis", "anis_lo", "anis_hi"))
    a_in, n_in = (anees >= lo) & (anees <= hi), (anis >= alo) & (anis <= ahi)
    end = float(summary["t_s"].to_numpy()[-1]) / div
    verdict = {"anees": float(anees[-1]), "anees_lo": float(lo[-1]), "anees_hi": float(hi[-1]),
               "anees_ok": bool(a_in[-1]), "nis": nis["ratio"], "nis_ok": bool(nis["inside"])}
    rows = [{"statistic": f"ANEES at the final time ({end:.4g} {tname}), 6 dof", "value": verdict["anees"],
             "lo": verdict["anees_lo"], "hi": verdict["anees_hi"], "badge": style.badge(verdict["anees_ok"]),
             "times": f"{int(a_in.sum())} of {len(a_in)} times"},
            {"statistic": f"total NIS / dof, all runs and images ({nis['dof']:.0f} dof, 2 per matched LOS)",
             "value": nis["ratio"], "lo": nis["lo"] / nis["dof"], "hi": nis["hi"] / nis["dof"],
             "badge": style.badge(verdict["nis_ok"]), "times": f"{int(n_in.sum())} of {len(n_in)} images (ANIS)"}]
    return rows, verdict


def _explanations(v: dict, frames) -> list[str]:
    """One sentence per verdict outside its band, with the study's known reason."""
    out = []
    if v["anees"] > v["anees_hi"]:
        out.append(f"ANEES {v['anees']:.2f} is above its band [{v['anees_lo']:.2f}, {v['anees_hi']:.2f}]: the "
                   "errors are larger than the filter's P. " + (MAP_ERROR if frames is not None else GEOMETRIC))
    elif v["anees"] < v["anees_lo"]:
        out.append(f"ANEES {v['anees']:.2f} is below its band: the filter's P is larger than its errors "
                   "(pessimistic, not overconfident).")
    if not v["nis_ok"] and v["nis"] < 1:
        why = "the σθ the filter assumes is larger than the noise the measurements carry"
        if frames is not None and "los_err_px_median" in frames.column_names:
            med = float(np.nanmedian(frames["los_err_px_median"].to_numpy()))
            why = ("the σθ the filter assumes (set before the runs to cover extraction, matching and map error in "
                   f"quadrature) is larger than the measured image error, a median {med:.2f} px from the true "
                   "projection of the matched database points (README point 4)")
        out.append(f"Total NIS / dof {v['nis']:.3f} is below its band: the innovations are smaller than the filter's "
                   f"R expects; {why}.")
    elif not v["nis_ok"]:
        out.append(f"Total NIS / dof {v['nis']:.3f} is above its band: the innovations are larger than R: the "
                   "measurements carry errors the filter does not model.")
    return out


def _conclusion(ss: dict, v: dict) -> str:
    """One sentence from the steady-state ratios and the two verdicts (the numbers of the tables above it)."""
    ratios = [ss[f"mc_3sig_{a}_{u}"] / ss[f"filter_3sig_{a}_{u}"] for a, u, *_ in _ROWS
              if ss.get(f"filter_3sig_{a}_{u}")]
    where = lambda ok: "inside" if ok else "outside"  # noqa: E731
    both = v["anees_ok"] and v["nis_ok"]
    text = (f"Conclusion: in the steady state the Monte Carlo 3σ is {min(ratios):.3g}–{max(ratios):.3g}× the "
            f"filter's own 3σ over the six RIC axes; ANEES at the final time ({v['anees']:.3g}) is "
            f"{where(v['anees_ok'])} its band and the total NIS / dof ({v['nis']:.4g}) {where(v['nis_ok'])} its band")
    return text + (": the filter's covariance describes its errors here." if both else
                   ": the filter's covariance does not describe its errors here (the reason follows).")


def _frames_note(frames) -> str:
    fr = {c: frames[c].to_numpy() for c in ("n_matched", "los_err_px_median") if c in frames.column_names}
    if len(fr) < 2:
        return ""
    return (f"Per image ({len(fr['n_matched'])} images of all runs): {np.mean(fr['n_matched']):.1f} matched LOS on "
            f"average, {100 * np.mean(fr['n_matched'] == 0):.0f} % with none; observed points a median "
            f"{np.nanmedian(fr['los_err_px_median']):.2f} px from the true projection of their database points.")


def coastline_section(name: str, table, stage: Path, pcrb_sigma: np.ndarray | None = None,
                      frames=None) -> tuple[str, str]:
    """(title, HTML) of the coastline section of filter table ``name`` (all runs on one time grid); writes
    ``<name>_coastline_{errors,consistency}.png`` and ``<name>_coastline_steady_state.csv`` into ``stage``.
    ``pcrb_sigma`` (K, 6): PCRB σ per RIC axis; ``frames``: the image mode's ``coastline_frames`` (None: geometric)."""
    runs, t = table["run"].to_numpy(), table["t_s"].to_numpy()
    n_runs = len(np.unique(runs))
    title = f"Coastline EKF (Straub & Christian Figs. 5-9): {name}"
    if len(t) % n_runs or len(np.unique(t)) != len(t) // n_runs:
        return title, render_blocks([{"kind": "text", "html": "Runs do not share one time grid; no coastline summary."}])
    pcrb = pcrb_sigma if pcrb_sigma is not None and len(pcrb_sigma) == len(t) // n_runs else None
    summary = per_time_summary(table, pcrb)
    mode = "image in the loop" if frames is not None else "geometric"
    ss, blocks = summary_blocks(name, summary, table, nis_total_test(table), stage, f"Coastline EKF, {mode}",
                                mode, frames=frames)
    write_csv(stage / f"{name}_coastline_steady_state.csv", [ss])
    return title, render_blocks(blocks + [{"kind": "links", "files": [f"{name}_coastline_steady_state.csv"]}])


def summary_blocks(name: str, summary, sample, nis: dict, stage: Path, figure_title: str, mode: str, frames=None,
                   unit: tuple[float, str] | None = None) -> tuple[dict, list[dict]]:
    """(:func:`.scoring.steady_state` plus ``runs`` and the verdicts, report blocks) of one per-time ``summary``
    (PCRB columns optional): tables, verdicts and both figures (``<name>_coastline_*.png`` in ``stage``); ``sample``:
    the per-run rows drawn as thin lines; ``nis``: :func:`.scoring.nis_band_test` of all runs; ``figure_title``
    and ``mode`` (``"geometric"`` or ``"image in the loop"``) for the texts; ``unit``: the report's time unit."""
    n_runs = int(summary["n_runs"].to_numpy()[0])
    pcrb = "pcrb_sig_r_m" in summary.column_names
    div, tname = unit if unit is not None else time_unit(summary["t_s"].to_numpy())
    err = plot_errors(sample, summary, stage / f"{name}_coastline_errors.png", figure_title, unit=(div, tname))
    cons = plot_consistency(summary, stage / f"{name}_coastline_consistency.png", figure_title, unit=(div, tname))
    ss = steady_state(summary)
    rows, verdict = _consistency(summary, nis, tname, div)
    anees, lo, hi = (summary[c].to_numpy() for c in ("anees", "anees_lo", "anees_hi"))
    ss.update(runs=n_runs, nis_total_over_dof=nis["ratio"], nis_total_inside_99=nis["inside"],
              anees_inside_99_fraction=float(np.mean((anees >= lo) & (anees <= hi))))
    cons_cols = [("statistic", "statistic"), ("value", "value"), ("lo", "χ² band low (99 %)"),
                 ("hi", "χ² band high (99 %)"), ("badge", "consistent?"), ("times", "inside its band at")]
    n_drawn = len(np.unique(sample["run"].to_numpy()[:]))
    blocks = [
        {"kind": "text", "html": f"{n_runs} runs, {mode} mode. Steady state: the last 20 % of the span, "
                                 f"{ss['window_start_s'] / div:.4g}–{ss['window_end_s'] / div:.4g} {tname}; 3σ of the "
                                 "Monte Carlo (3 × RMS over runs), of the filter (3 × RMS of its σ)"
                                 + (" and of the posterior Cramér–Rao bound" if pcrb else
                                    "; the posterior Cramér–Rao bound needs the truth geometry and is published by "
                                    "<code>python -m renderlab.studies.coastline_ekf.publish</code>") + "."},
        {"kind": "table", "html": _steady_table(ss)},
        {"kind": "h3", "text": "Consistency (99 % two-sided χ² bands)"},
        {"kind": "table", "html": html_table(rows, cons_cols, left=("statistic",), raw=("badge",))},
        {"kind": "text", "html": f"ANEES inside its 99 % χ²(6N)/N band at {100 * ss['anees_inside_99_fraction']:.0f} % "
                                 "of the times. The NIS of an image has 2m degrees of freedom (m matched LOS), so it is "
                                 "scored against its own band, never against a 2-dof one."},
        {"kind": "text", "html": _conclusion(ss, verdict)},
        *({"kind": "text", "html": s} for s in _explanations(verdict, frames)),
        *([{"kind": "text", "html": _frames_note(frames)}] if frames is not None and _frames_note(frames) else []),
        {"kind": "figure", "png": err[0], "svg": err[1], "alt": f"{name} coastline errors",
         "caption": f"Errors per RIC axis against time ({tname}): {min(n_drawn, 25)} of {n_runs} runs drawn, the ±3σ "
                    f"curves over all {n_runs}."},
        {"kind": "figure", "png": cons[0], "svg": cons[1], "alt": f"{name} coastline consistency",
         "caption": "ANEES and ANIS per dof against their 99 % χ² bands; crosses: outside the band."}]
    return ss, blocks


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
    for a, u, _, scale, shown in _ROWS:
        unit = shown.replace("/", "p")                                   # m, mmps
        row[f"final_rms_{a}_{unit}"] = float(s[f"mc_rms_{a}_{u}"].to_numpy()[-1] * scale)
        row[f"final_filter_sig_{a}_{unit}"] = float(s[f"filter_sig_{a}_{u}"].to_numpy()[-1] * scale)
    t = core["t_s"].to_numpy()
    for a, _ in _POS:                    # the run-mean error at the last time and its standard error over runs
        row[f"final_mean_{a}_m"] = float(s[f"mc_mean_{a}_m"].to_numpy()[-1])
        final = core[f"err_{a}_m"].to_numpy()[t == t.max()]
        row[f"final_mean_sem_{a}_m"] = float(np.std(final, ddof=1) / np.sqrt(n)) if n > 1 else np.nan
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


def comparison_sections(tables: dict, stage: Path) -> list[tuple[str, str]]:
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
    return [("Coastline EKF: image in the loop vs idealised measurements", render_blocks(blocks))]
