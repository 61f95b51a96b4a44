"""Report section of ``descent_gnc`` from its ``gnc_images`` and ``gnc_runs`` tables alone (:mod:`.scoring` says
how each number is made): ``gnc_summary.csv`` (per method and mode), ``gnc_timeseries.csv`` (per method, mode,
image and run set), ``gnc_track_loss.csv`` (per lost flight), three figures (:mod:`.report_figures`): landing
dispersion ellipses, estimation vs control error over time, ANEES/ANIS against their χ² bands; a table with
PASS/FAIL and one conclusion sentence per method."""

from __future__ import annotations

import html
from pathlib import Path

from renderlab.report import csvio
from renderlab.report.style import badge, fmt
from renderlab.studies.descent_gnc.report_figures import consistency_figure, dispersion_figure, history_figure
from renderlab.studies.descent_gnc.scoring import cols, lost_keys, summary, timeseries, track_loss_rows


def write_csv(rows: list[dict], path: Path) -> None:
    """:func:`renderlab.report.csvio.write_csv`; an empty table is the header ``none``."""
    if rows:
        csvio.write_csv(path, rows)
    else:
        Path(path).write_text("none\n", encoding="utf-8")


def _ci(r: dict, key: str, digits: int = 3) -> str:
    return f"{fmt(r[key], digits)} [{fmt(r[key + '_lo'], digits)}, {fmt(r[key + '_hi'], digits)}]"


def _table(rows: list[dict]) -> str:
    head = ("method", "mode", "runs (touchdowns)", "touchdown |Δr_h| median [95 % CI] / p95 (m)",
            "runs' 3σ / filter's claimed 3σ, horizontal (m)", "vertical speed error mean [95 % CI] (m/s)",
            "Δv mean [95 % CI] (m/s)", "propellant mean (kg)", "ANEES/6 all runs [95 % CI]",
            "ANEES/6 kept track", "image times in NEES band", "ANIS/dof all runs [95 % CI]", "ANIS/dof kept track",
            "track lost (runs)")
    out = ['<div style="overflow-x:auto"><table><tr>' + "".join(f"<th>{html.escape(h)}</th>" for h in head)
           + "</tr>"]
    for r in rows:
        kept_nees = r["kept_anees_over_6_lo"] <= 1.0 <= r["kept_anees_over_6_hi"]
        kept_nis = r["kept_anis_per_dof_lo"] <= 1.0 <= r["kept_anis_per_dof_hi"]
        cells = [html.escape(r["method"]), r["mode"], f"{r['n_runs']} ({r['touchdowns']})",
                 f"{_ci(r, 'td_h_median_m')} / {fmt(r['td_h_p95_m'], 3)}",
                 f"{fmt(r['td_h_3sig_runs_m'], 3)} / {fmt(r['td_h_3sig_claimed_m'], 3)}",
                 _ci(r, "td_vu_err_mean_mps", 2), _ci(r, "delta_v_mean_mps"), fmt(r["propellant_mean_kg"], 3),
                 _ci(r, "anees_over_6") + " " + badge(r["anees_pass"]),
                 _ci(r, "kept_anees_over_6") + " " + badge(kept_nees), f"{r['anees_times_in_band']:.0%}",
                 _ci(r, "anis_per_dof") + " " + badge(r["anis_pass"]),
                 _ci(r, "kept_anis_per_dof") + " " + badge(kept_nis), str(r["track_lost_runs"])]
        out.append("<tr>" + "".join(f"<td>{c}</td>" for c in cells) + "</tr>")
    return "\n".join(out) + "</table></div>"


def _loss_html(loss: list[dict]) -> str:
    if not loss:
        return "<p>Track loss: none, in any flight (closed loops and replays).</p>"

    def item(x: dict) -> str:
        again = "re-acquired" if x["reacquired"] else "not re-acquired"
        return (f"<li>{html.escape(x['method'])} {x['mode']} run {x['run']}: {x['cause']} at t = {x['t_s']:.0f} s "
                f"({x['altitude_m']:.0f} m), {again}; initial velocity error {x['init_vel_err_max_sigma']:.1f}σ "
                f"(largest axis); touchdown miss {x['td_h_m']:.2f} m</li>")

    items = "".join(item(x) for x in loss)
    return f"<p>Track loss ({len(loss)} flights; causes as the onboard loop saw them):</p><ul>{items}</ul>"


def conclusions(rows: list[dict]) -> str:
    """One sentence per method from its closed-loop and replay rows."""
    out = []
    by = {(r["method"], r["mode"]): r for r in rows}
    for m in sorted({r["method"] for r in rows}):
        c, p = by.get((m, "closed")), by.get((m, "replay"))
        if c is None:
            continue
        words = (f"<b>{html.escape(m)}</b>: flying its own estimate, the vehicle touched down "
                 f"{c['td_h_median_m']:.3g} m [{c['td_h_median_m_lo']:.3g}, {c['td_h_median_m_hi']:.3g}] from the "
                 f"target (median; 95th percentile {c['td_h_p95_m']:.3g} m, the filter claiming a 3σ of "
                 f"{c['td_h_3sig_claimed_m']:.3g} m) with {c['delta_v_mean_mps']:.3g} m/s of Δv, its filter "
                 f"{'consistent' if c['anees_pass'] else 'inconsistent'} (ANEES/6 {c['anees_over_6']:.3g}, "
                 f"{'PASS' if c['anees_pass'] else 'FAIL'}), and lost track in {c['track_lost_runs']} of "
                 f"{c['n_runs']} runs")
        if p is not None:
            words += (f"; in the open-loop replay the same draws land {p['td_h_median_m']:.3g} m from the target "
                      f"while the same filter's estimate is {p['nav_h_median_m']:.3g} m off at contact (median)")
        out.append(words + ".")
    return "<p>Conclusion. " + " ".join(out) + "</p>"


NOTE = ("<p>Intervals: 95 % percentile bootstraps resampling whole runs (runs are independent; a run's images are "
        "not). ANEES/6 and ANIS/dof: 1 is consistent; PASS when 1 is inside the interval. The per-image bands in "
        "the consistency figure are the two-sided 95 % χ² bands of the run average. \"Kept track\": the runs whose "
        "flight never had a track loss (consecutive missed images); every run is in the \"all runs\" columns. "
        "Closed: guidance flies on the method's own filter; replay: guidance flies on the truth, and every "
        "method's filter runs on the same images along that path (the open-loop design of "
        "results/descent_navigation). Touchdown = contact with the site DEM.</p>")


def report_sections(tables: dict, out_dir) -> list[tuple[str, str]]:
    """The study's section: CSVs and figures into ``out_dir`` (module docstring)."""
    it, rt = tables.get("gnc_images"), tables.get("gnc_runs")
    if it is None or rt is None or rt.num_rows == 0:
        return []
    out_dir = Path(out_dir)
    im, r = cols(it), cols(rt)
    ts_rows = timeseries(im, lost_keys(r))
    rows = summary(im, r, ts_rows)
    loss = track_loss_rows(r)
    write_csv(rows, out_dir / "gnc_summary.csv")
    write_csv(ts_rows, out_dir / "gnc_timeseries.csv")
    write_csv(loss, out_dir / "gnc_track_loss.csv")
    figs = dispersion_figure(r, out_dir) + history_figure(ts_rows, out_dir) + consistency_figure(ts_rows, out_dir)
    imgs = "".join(f'<p><img src="{f}" style="max-width:100%"></p>' for f in figs if f and f.endswith(".png"))
    return [("Closed-loop GN&C descent", _table(rows) + conclusions(rows) + _loss_html(loss) + NOTE + imgs)]
