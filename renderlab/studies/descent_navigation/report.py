"""Report section of ``descent_navigation`` (the lab's report style, :mod:`renderlab.report.style`): from the
published tables alone (:func:`.publish.publish_tables`, applied first to raw campaign tables too), ``descent_summary.csv`` (one row per method),
``descent_timeseries.csv`` (per method and image), and three figures (PNG; SVG with ``--svg``): position and velocity error vs
time with the filter's 3σ, and ANEES / ANIS vs time with their 95 % χ² bands and pass/fail marks
(:mod:`.scoring` says how each number is made); the independence scores (:mod:`.report_independence`) and, for
injected-error sources, the bias sweep (:mod:`.report_sources`)."""

from __future__ import annotations

import html
import math
from pathlib import Path

import numpy as np

from renderlab.report.axes import note_outside, typical_limit
from renderlab.report.csvio import write_csv
from renderlab.report.html_table import plain_table
from renderlab.report.style import badge, fmt, method_colors, plt, save
from renderlab.studies.descent_navigation.publish import IMAGES, RUNS, image_index, publish_tables
from renderlab.studies.descent_navigation.report_independence import independence_section
from renderlab.studies.descent_navigation.report_sources import sources_section
from renderlab.studies.descent_navigation.scoring import POS, VEL, columns, method_summary, timeseries, tracked


def error_figure(ftab, images: dict, kind: str, out_dir: Path) -> list[str]:
    """Errors of every run that kept track (thin) and ±3σ RMS of the filter (dashed) per method (columns) and site
    axis (rows); the runs that lost track are counted in the title, not drawn (their errors reach 10–300 m). Each
    panel's range is robust (:func:`renderlab.report.axes.typical_limit`: what holds 98 % of the errors at 80 % of
    the times, at least 1.1 × the median ±3σ) and the samples left outside are counted in the panel; ``images``:
    ``{(method, frame): row}`` of ``descent_images`` (the mean squared 1σ per image, ``sig2_fig_*``)."""
    cols, unit = (POS, "m") if kind == "position" else (VEL, "m/s")
    sig = [f"sig2_fig_{c[4:]}" for c in cols]
    every = columns(ftab, ("run", "method"))
    c = columns(tracked(ftab), ("run", "method", "frame", "t_s", *cols))
    methods = sorted(set(c["method"].tolist()))
    colors = method_colors(methods)
    pyplot = plt()
    fig, axes = pyplot.subplots(3, len(methods), figsize=(3.6 * len(methods), 7.0), sharex=True, squeeze=False)
    for j, m in enumerate(methods):
        for i, (e, s) in enumerate(zip(cols, sig)):
            ax = axes[i, j]
            sel = (c["method"] == m) & (c["frame"] >= 0)
            for r in sorted(set(c["run"][sel].tolist())):
                rr = sel & (c["run"] == r)
                ax.plot(c["t_s"][rr], c[e][rr], color="0.55", lw=0.4, alpha=0.5)
            at = sorted({float(c["t_s"][sel & (c["frame"] == k)][0]): k for k in set(c["frame"][sel].tolist())}.items())
            ts = [t for t, _ in at]
            three = np.array([3 * np.sqrt(images[(m, int(k))][s]) for _, k in at])
            ax.plot(ts, three, "--", color=colors[m], lw=1.5, label="±3σ (filter, RMS over runs)")
            ax.plot(ts, -three, "--", color=colors[m], lw=1.5)
            lim = typical_limit(c[e][sel], c["t_s"][sel], floor=1.1 * float(np.nanmedian(three)) if len(ts) else 0.0)
            ax.set_ylim(-lim, lim)  # robust: not set by one run's first sample or the first seconds' 3σ
            note_outside(ax, c[e][sel], -lim, lim, times=c["t_s"][sel])
            ax.set_ylabel(f"{'ENU'[i]} {kind} error ({unit})")
            if i == 0:
                n_all = len(set(every["run"][every["method"] == m].tolist()))
                n_ok = len(set(c["run"][c["method"] == m].tolist()))
                ax.set_title(f"{m}: {n_ok} runs ({n_all - n_ok} lost track, not drawn)", fontsize=9)
                ax.plot([], [], color="0.55", lw=0.8, label="each run")
                ax.legend(loc="upper right", fontsize=7)
            if i == 2:
                ax.set_xlabel("time (s)")
    fig.tight_layout()
    return save(fig, out_dir / f"descent_{kind}_error")


def consistency_figure(ts_rows: list[dict], out_dir: Path) -> list[str]:
    """ANEES/6 and ANIS/dof vs time per method, the 95 % bands shaded, inside (●) / outside (✕)."""
    methods = sorted({r["method"] for r in ts_rows})
    colors = method_colors(methods)
    pyplot = plt()
    fig, axes = pyplot.subplots(1, 2, figsize=(10, 3.8), squeeze=False)
    for ax, (key, lo, hi, inside, title) in zip(axes[0], (("anees", "anees_lo", "anees_hi", "anees_inside",
                                                          "ANEES / 6 (state, 6 dof)"),
                                                         ("anis_per_dof", "anis_lo", "anis_hi", "anis_inside",
                                                          "ANIS / dof (landmark pixels)"))):
        scale = 6.0 if key == "anees" else 1.0
        for m in methods:
            rows = [r for r in ts_rows if r["method"] == m and r["frame"] >= 0 and np.isfinite(r[key])]
            t = np.array([r["t_s"] for r in rows])
            v = np.array([r[key] for r in rows]) / scale
            ok = np.array([bool(r[inside]) for r in rows])
            ax.fill_between(t, [r[lo] / scale for r in rows], [r[hi] / scale for r in rows], color=colors[m],
                            alpha=0.12, lw=0)
            ax.plot(t, v, color=colors[m], lw=1.2, label=m)
            ax.plot(t[ok], v[ok], "o", color=colors[m], ms=4)
            ax.plot(t[~ok], v[~ok], "x", color=colors[m], ms=6, mew=1.5)
        ax.axhline(1.0, color="k", lw=0.6)
        ax.set_yscale("log")
        ax.set_xlabel("time (s)")
        ax.set_ylabel(f"{title.split(' (')[0]} (—)")
        ax.set_title(f"{title}\nshaded: 95 % χ² band; ● inside (PASS), ✕ outside (FAIL)", fontsize=8)
        ax.legend(fontsize=8)
    fig.tight_layout()
    return save(fig, out_dir / "descent_consistency")


def _html_table(summary: list[dict]) -> str:
    head = ("method", "runs", "ANEES/6 [95 % CI]", "times in NEES band", "ANIS/dof [95 % CI]", "times in NIS band",
            "at 50 m (last image) |δr| median / p95 (m)", "at 50 m 3σ (m)", "track lost (runs)",
            "kept bias s, l (px)", "gated / flagged")
    out = []
    for r in summary:
        ok_nees = r["anees_over_6_lo"] <= 1.0 <= r["anees_over_6_hi"]
        ok_nis = r["anis_per_dof_lo"] <= 1.0 <= r["anis_per_dof_hi"]
        cells = [r["method"], r["n_runs"],
                 f"{fmt(r['anees_over_6'], 3)} [{fmt(r['anees_over_6_lo'], 3)}, {fmt(r['anees_over_6_hi'], 3)}] "
                 + badge(ok_nees), f"{r['anees_inside_frac']:.0%}",
                 f"{fmt(r['anis_per_dof'], 3)} [{fmt(r['anis_per_dof_lo'], 3)}, {fmt(r['anis_per_dof_hi'], 3)}] "
                 + badge(ok_nis), f"{r['anis_inside_frac']:.0%}",
                 f"{fmt(r['touchdown_pos_err_median_m'], 3)} / {fmt(r['touchdown_pos_err_p95_m'], 3)}",
                 fmt(r["touchdown_pos_3sig_rms_m"], 3), r["track_lost_runs"],
                 f"{fmt(r.get('kept_bias_s_px', math.nan), 2)}, {fmt(r.get('kept_bias_l_px', math.nan), 2)}",
                 f"{r['gated_frac']:.1%} / {r['flagged_frac']:.1%}"]
        out.append(cells)
    return plain_table(head, out)


def _word(v: float, lo: float, hi: float, what: str) -> str:
    """How a normalised statistic (1 = consistent) reads against its 95 % interval; ``what``: "errors" (NEES) or
    "innovations" (NIS)."""
    if not all(map(math.isfinite, (v, lo, hi))):
        return "not available"
    if lo <= 1.0 <= hi:
        return f"{v:.3g} [{lo:.3g}, {hi:.3g}], consistent (1 inside its 95 % interval)"
    side = "larger" if lo > 1.0 else "smaller"
    return f"{v:.3g} [{lo:.3g}, {hi:.3g}], {what} {side} than the filter predicts"


def conclusion_html(summary: list[dict]) -> str:
    """One sentence per method from the summary rows (the numbers of the table above it)."""
    out = []
    for r in summary:
        out.append(f"<b>{html.escape(str(r['method']))}</b>: ANEES/6 "
                   f"{_word(r['anees_over_6'], r['anees_over_6_lo'], r['anees_over_6_hi'], 'errors')}; ANIS/dof "
                   f"{_word(r['anis_per_dof'], r['anis_per_dof_lo'], r['anis_per_dof_hi'], 'innovations')}; "
                   f"position error at the last image {r['touchdown_pos_err_median_m']:.3g} m median, "
                   f"{r['touchdown_pos_err_p95_m']:.3g} m 95th percentile (filter 3σ {r['touchdown_pos_3sig_rms_m']:.3g}"
                   f" m); track lost in {r['track_lost_runs']} of {r['n_runs']} runs.")
    return ("<p>Conclusion (the last image is 50 m above the site, where the descent's \"touchdown\" numbers are "
            "taken). " + " ".join(out) + "</p>") if out else ""


def report_sections(tables: dict, out_dir) -> list[tuple[str, str]]:
    """The study's section: CSVs and figures into ``out_dir`` (module docstring)."""
    tables = publish_tables(tables)                # raw or published: the report reads the published form only
    ftab = tables.get("descent_filter")
    if ftab is None or ftab.num_rows == 0:
        return []
    out_dir = Path(out_dir)
    images = image_index(tables)
    ts_rows = timeseries(ftab, images)
    summary = method_summary(ftab, tables.get(RUNS), ts_rows)
    write_csv(out_dir / "descent_summary.csv", summary)
    write_csv(out_dir / "descent_timeseries.csv", ts_rows)
    figs = error_figure(ftab, images, "position", out_dir) + error_figure(ftab, images, "velocity", out_dir) \
        + consistency_figure(ts_rows, out_dir)
    extra = ""
    if "rho_state" in tables[IMAGES].column_names:  # campaigns that wrote the whitened errors (map-state study)
        extra, more = independence_section(ftab, tables, images, ts_rows, out_dir)
        figs += more
    if "src_kind" in ftab.column_names:            # campaigns with injected-error sources (.sources)
        more_html, more = sources_section(ftab, images, summary, out_dir)
        extra += more_html
        figs += more
    imgs = "".join(f'<p><img src="{f}" style="max-width:100%"></p>' for f in figs if f and f.endswith(".png"))
    note = ("<p>ANEES/6 and ANIS/dof: 1 is consistent; intervals are 95 % bootstraps over whole runs (the images of "
            "a run are correlated; when every run flies the same onboard map they leave out the map-to-map "
            "variation). \"Touchdown\" in the CSV columns is a proxy: the position error norm at the last image, "
            "50 m above the site. Track lost: "
            "a run with ≥ N consecutive images without an accepted landmark (N = track_loss_frames). Consistency, the "
            "landmark statistics and the figures are over the runs that kept track; ANEES/ANIS over every run are the "
            "*_all columns of descent_summary.csv.</p>")
    return [("Descent navigation", _html_table(summary) + conclusion_html(summary) + note + extra + imgs)]
