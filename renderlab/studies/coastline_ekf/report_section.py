"""The coastline-EKF section of ``renderlab report``: Figs. 5-9, ANEES/ANIS with their χ² bands, PCRB.

The generic filter section of :mod:`renderlab.report.campaign_report` scores every ``err_*`` column and takes
2 degrees of freedom per NIS row; the coastline NIS has 2m (m matched LOS in that image), so this section
recomputes the consistency with :func:`renderlab.studies.coastline_ekf.scoring.per_time_summary` (99 % two-sided
χ² bands, Bar-Shalom §5.4) and draws the paper's figures. The posterior Cramér–Rao bound needs the truth
geometry; :mod:`renderlab.studies.coastline_ekf.publish` adds it, the campaign report shows it when given.
Hooked in through ``report_sections`` of :mod:`renderlab.studies.coastline_ekf.study`.
"""

from __future__ import annotations

import csv
import html
from pathlib import Path

import numpy as np

__all__ = ["is_coastline_table", "coastline_section"]


def is_coastline_table(table) -> bool:
    """A coastline filter table: the filter columns plus the per-image LOS count ``n_meas``."""
    return {"run", "t_s", "nees", "nis", "n_meas"} <= set(table.column_names)


def coastline_section(name: str, table, stage: Path, pcrb_sigma: np.ndarray | None = None) -> tuple[str, str]:
    """Write ``<name>_coastline_{errors,consistency}.png`` and ``<name>_coastline_steady_state.csv`` into
    ``stage``; return the HTML section (title, body). ``pcrb_sigma`` (K, 6): optional PCRB σ per RIC axis."""
    from renderlab.studies.coastline_ekf.figures import plot_consistency, plot_errors
    from renderlab.studies.coastline_ekf.scoring import nis_total_test, per_time_summary, steady_state

    runs = table["run"].to_numpy()
    t = table["t_s"].to_numpy()
    n_runs = len(np.unique(runs))
    if len(t) % n_runs or len(np.unique(t)) != len(t) // n_runs:
        return (f"Coastline EKF: {name}", "<p>Runs do not share one time grid; no coastline summary.</p>")
    pcrb = pcrb_sigma if pcrb_sigma is not None and len(pcrb_sigma) == len(t) // n_runs else None
    summary = per_time_summary(table, pcrb)
    title = f"campaign table {name}"
    plot_errors(table, summary, stage / f"{name}_coastline_errors.png", title)
    plot_consistency(summary, stage / f"{name}_coastline_consistency.png", title)
    ss = steady_state(summary)
    nis = nis_total_test(table)
    anees, lo, hi = (summary[c].to_numpy() for c in ("anees", "anees_lo", "anees_hi"))
    ss.update(runs=n_runs, nis_total_over_dof=nis["ratio"], nis_total_inside_99=nis["inside"],
              anees_inside_99_fraction=float(np.mean((anees >= lo) & (anees <= hi))))
    with open(stage / f"{name}_coastline_steady_state.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(ss), lineterminator="\n")
        w.writeheader()
        w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in ss.items()})
    cells = []
    for a, u, scale, unit in (("r", "m", 1, "m"), ("i", "m", 1, "m"), ("c", "m", 1, "m"),
                              ("vr", "mps", 1e3, "mm/s"), ("vi", "mps", 1e3, "mm/s"), ("vc", "mps", 1e3, "mm/s")):
        mc, fl = ss[f"mc_3sig_{a}_{u}"] * scale, ss[f"filter_3sig_{a}_{u}"] * scale
        pc = ss.get(f"pcrb_3sig_{a}_{u}")
        cells.append(f"<tr><td>{a}</td><td>{mc:.4g} {unit}</td><td>{fl:.4g} {unit}</td><td>"
                     + (f"{pc * scale:.4g} {unit}" if pc is not None else "–") + "</td></tr>")
    body = (f"<p>Steady state (last 20 % of the span, {ss['window_start_s']:.0f}–{ss['window_end_s']:.0f} s): "
            "3σ of the Monte Carlo (3 × RMS over runs), of the filter (3 × RMS of its σ) and of the posterior "
            "Cramér–Rao bound (when given). RIC axes of the true orbit.</p>"
            "<table><tr><th>axis</th><th>Monte Carlo 3σ</th><th>filter 3σ</th><th>PCRB 3σ</th></tr>"
            + "".join(cells) + "</table>"
            f"<p>ANEES inside its 99 % χ²(6N)/N band at {100 * ss['anees_inside_99_fraction']:.0f} % of the times; "
            f"total NIS / dof = {nis['ratio']:.3f} ({'inside' if nis['inside'] else 'outside'} its 99 % band, "
            f"{nis['dof']:.0f} dof, 2 per matched LOS).</p>"
            f'<p><img src="{html.escape(name)}_coastline_errors.png"></p>'
            f'<p><img src="{html.escape(name)}_coastline_consistency.png"></p>'
            f'<p>Table: <a href="{html.escape(name)}_coastline_steady_state.csv">{html.escape(name)}'
            "_coastline_steady_state.csv</a></p>")
    return (f"Coastline EKF (Straub & Christian Figs. 5-9): {name}", body)
