"""The published layout of the geometric coastline-EKF Monte Carlo (Straub & Christian, Table 1 and Figs. 5-9):
the per-time and per-run summary tables every figure and number needs, so that ``renderlab report FOLDER``
regenerates the whole report from them alone, with no re-run. The layout is the campaign publish layout
(:mod:`renderlab.campaign.publish`)::

    FOLDER/
      campaign.json                        plan.study = coastline_ekf, runs, seed, the options of every orbit
      runs.json                            one status per run index
      tables/coastline_orbits.parquet      one row per orbit: options, geometry counts, seconds
      tables/coastline_timeseries.parquet  one row per orbit and time: per-time summary of all runs, PCRB σ
      tables/coastline_run_totals.parquet  one row per orbit and run: NIS sum and its dof, NEES first / last
      tables/coastline_sample_runs.parquet the RIC errors of the first 25 runs (float32; the thin lines of the
                                           error figures, drawn only)
      tables/coastline_runs.parquet        (``--keep-runs``) every run's rows; the per-time summary is then
                                           recomputed from them (PCRB σ from the time series)
      report/                              ``renderlab report FOLDER``: summary.csv, table1.md, figures, index.html

Every table has a ``case`` column (the orbit name, :data:`~renderlab.studies.coastline_ekf.geometric.PAPER_ORBITS`).

References
----------
M. N. Straub and J. A. Christian, "Autonomous Optical Navigation for Earth-Observing Satellites Using
Coastline Matching", West Virginia University, AIAA paper, c. 2015 (Table 1, Figs. 5-9, eq. 18).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from renderlab.campaign import store
from renderlab.report.csvio import write_csv
from renderlab.studies.coastline_ekf.figures import time_unit
from renderlab.studies.coastline_ekf.report_section import _render, summary_blocks
from renderlab.studies.coastline_ekf.scoring import ERR, _columns, nis_band_test, per_time_summary

__all__ = ["TABLES", "orbit_tables", "sample_table", "write_folder", "is_geometric", "report_sections", "PAPER_TABLE1"]

TABLES = ("coastline_orbits", "coastline_timeseries", "coastline_run_totals", "coastline_sample_runs",
          "coastline_runs")
N_SAMPLE = 25  #: runs kept per orbit in ``coastline_sample_runs``

PAPER_TABLE1 = {  # case: along-track, cross-track, radial position [km]; along, cross, radial velocity [m/s]
    "i00_h1000": (1.0, 1.4, 5.0, 5.0, 1.4, 1.0), "i45_h1000": (1.0, 1.4, 5.0, 5.0, 1.4, 1.0),
    "i90_h1000": (0.6, 1.3, 3.0, 3.0, 1.3, 0.6), "i45_h500": (1.0, 1.4, 4.5, 4.8, 1.5, 1.1),
    "i90_h500": (0.5, 1.3, 1.8, 2.0, 1.4, 0.6),
}


def _with_case(table, case: str):
    import pyarrow as pa

    return table.add_column(0, "case", pa.array([case] * table.num_rows, pa.string()))


def orbit_tables(case: str, options, geometry, runs_table, summary, seconds: dict, keep_runs: bool) -> dict:
    """The published tables of one orbit: ``{name: pyarrow.Table}`` (names of :data:`TABLES`).

    Parameters
    ----------
    case : str
        Orbit name.
    options : CoastlineGeometricOptions
        The study options it ran with.
    geometry : Geometry
        Its truth geometry (counts of images and matched points).
    runs_table : pyarrow.Table
        Every run's filter rows.
    summary : pyarrow.Table
        :func:`~renderlab.studies.coastline_ekf.scoring.per_time_summary` of all runs, with the PCRB σ.
    seconds : dict
        ``{"geometry": s, "monte_carlo": s}`` wall times.
    keep_runs : bool
        Also return every run's rows (``coastline_runs``).
    """
    import pyarrow as pa


    c, N, K = _columns(runs_table.select(["run", "t_s", "nees", "nis", "n_meas"]))
    totals = pa.table({"run": c["run"][:, 0], "nis_sum": np.nansum(c["nis"], axis=1),
                       "nis_dof": np.sum(2 * c["n_meas"], axis=1).astype(np.float64),
                       "nees_first": c["nees"][:, 0], "nees_last": c["nees"][:, -1]})
    orbit = {"altitude_km": options.altitude_m / 1e3, "inclination_deg": math.degrees(options.inclination_rad),
             "runs": N, "duration_s": float(geometry.t_s[-1]), "images": int(len(geometry.t_s) - 1),
             "images_with_coastline": int((geometry.n_meas > 0).sum()),
             "mean_points_per_image": float(geometry.n_meas[1:].mean()),
             "sigma_theta_mrad": options.sigma_theta_rad * 1e3, "points_per_image": options.points_per_image,
             "cadence_s": options.cadence_s, "truth_model": getattr(options, "truth_model", "j2_rk4"),
             "seconds_geometry": round(seconds["geometry"], 1), "seconds_monte_carlo": round(seconds["monte_carlo"], 1)}
    core = runs_table.drop([n for n in ("campaign",) if n in runs_table.column_names])
    out = {"coastline_orbits": pa.table({k: [v] for k, v in orbit.items()}), "coastline_timeseries": summary,
           "coastline_run_totals": totals,
           "coastline_sample_runs": sample_table(core)}
    if keep_runs:  # the filter table as the study wrote it (FILTER_CORE: has_result, reason)
        out["coastline_runs"] = core
    return {k: _with_case(v, case) for k, v in out.items()}


def write_folder(out: Path, parts: list[dict], plan: dict) -> None:
    """Write ``campaign.json``, ``runs.json`` and ``tables/`` (the orbits' tables concatenated, zstd) into ``out``;
    other entries of ``out`` (README, report) are kept."""
    import pyarrow as pa
    import pyarrow.parquet as pq


    names = [n for n in TABLES if any(n in p for p in parts)]
    with store.staged_folder(Path(out), "the published study") as stage:
        (stage / "tables").mkdir()
        for n in names:
            t = pa.concat_tables([p[n] for p in parts if n in p])
            pq.write_table(t, str(stage / "tables" / f"{n}.parquet"), compression="zstd", compression_level=9)
        manifest = {"format": "renderlab.campaign/1", "name": plan["name"], "versions": store._versions(),
                    "plan": {"study": "coastline_ekf", "runs": plan["runs"], "scenario": plan["scenario"],
                             "seed": {"entropy": plan["seed"],
                                      "run_seed": "SeedSequence([entropy, orbit index]).spawn(runs)[run]"}}}
        (stage / "campaign.json").write_text(json.dumps(manifest, indent=1, sort_keys=True) + "\n", encoding="utf-8")
        statuses = [{"run": i, "status": "ok", "error": "", "tables": names} for i in range(plan["runs"])]
        (stage / "runs.json").write_text(json.dumps(statuses, indent=1) + "\n", encoding="utf-8")


def is_geometric(tables: dict) -> bool:
    """Tables of this layout (as opposed to a campaign's ``coastline_filter``)."""
    return "coastline_timeseries" in tables and "coastline_run_totals" in tables


def sample_table(runs_table):
    """``coastline_sample_runs``: ``run``, ``t_s`` and the RIC errors (float32: drawn only, never scored) of the
    first :data:`N_SAMPLE` runs."""
    import pyarrow as pa


    t = _first_runs(runs_table.select(["run", "t_s", *ERR]))
    for name in ERR:
        t = t.set_column(t.column_names.index(name), name, t[name].cast(pa.float32()))
    return t


def _first_runs(table):
    """The rows of the first :data:`N_SAMPLE` run indices."""
    import pyarrow as pa

    run = table["run"].to_numpy()
    return table.filter(pa.array(np.isin(run, np.unique(run)[:N_SAMPLE])))


def _case(table, case: str):
    import pyarrow.compute as pc

    return table.filter(pc.equal(table["case"], case)).drop(["case"])


def _orbit_report(case: str, tables: dict, stage: Path, unit) -> tuple[dict, list[dict]]:
    """Steady-state row and report blocks of one orbit, from its published tables."""
    orbit = _case(tables["coastline_orbits"], case).to_pylist()[0]
    summary = _case(tables["coastline_timeseries"], case)
    if "coastline_runs" in tables:  # every run's rows: the summary is recomputed from them, the PCRB σ kept
        runs = _case(tables["coastline_runs"], case)
        pcrb = [f"pcrb_sig_{a}" for a in ("r_m", "i_m", "c_m", "vr_mps", "vi_mps", "vc_mps")]
        has = all(p in summary.column_names for p in pcrb)
        summary = per_time_summary(runs, np.stack([summary[p].to_numpy() for p in pcrb], axis=1) if has else None)
        sample = _first_runs(runs)
    else:
        sample = _case(tables["coastline_sample_runs"], case)
    totals = _case(tables["coastline_run_totals"], case)
    nis = nis_band_test(float(np.sum(totals["nis_sum"].to_numpy())), float(np.sum(totals["nis_dof"].to_numpy())))
    title = (f"{case}: i = {orbit['inclination_deg']:.0f}°, h = {orbit['altitude_km']:.0f} km, "
             f"σθ = {orbit['sigma_theta_mrad']:.2f} mrad")
    ss, blocks = summary_blocks(case, summary, sample, nis, stage, title, "geometric", unit=unit)
    row = {"case": case, **{k: orbit[k] for k in ("altitude_km", "inclination_deg", "runs", "duration_s", "images",
                                                  "images_with_coastline", "mean_points_per_image")}}
    row.update({k: v for k, v in ss.items() if k != "runs"})
    row.update(seconds_geometry=orbit["seconds_geometry"], seconds_monte_carlo=orbit["seconds_monte_carlo"])
    return row, blocks


def table1_markdown(rows: list[dict]) -> str:
    """Table 1's layout: our steady-state Monte Carlo 3σ beside the paper's values."""
    lines = ["Steady-state Monte Carlo 3σ (3 x RMS over runs and the last 20 % of the span), ours vs Table 1.", "",
             "| orbit | along-track pos | cross-track pos | radial pos | along-track vel | cross-track vel | radial vel |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        ours = [r["mc_3sig_i_m"], r["mc_3sig_c_m"], r["mc_3sig_r_m"], r["mc_3sig_vi_mps"], r["mc_3sig_vc_mps"],
                r["mc_3sig_vr_mps"]]
        paper = PAPER_TABLE1.get(r["case"])
        ref = [f" (paper {paper[j]} {'km' if j < 3 else 'm/s'})" if paper else "" for j in range(6)]
        cells = [f"{ours[j]:.1f} m{ref[j]}" for j in range(3)] + [f"{1e3 * ours[j]:.2f} mm/s{ref[j]}" for j in range(3, 6)]
        lines.append(f"| {r['inclination_deg']:.0f}°, {r['altitude_km']:.0f} km | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def report_sections(tables: dict, stage: Path) -> list[tuple[str, str]]:
    """``renderlab report`` sections of a published geometric folder: one per orbit (Figs. 5-9, consistency),
    and ``summary.csv`` (one row per orbit) and ``table1.md`` written into ``stage``."""
    cases = list(dict.fromkeys(tables["coastline_orbits"]["case"].to_pylist()))
    unit = time_unit(tables["coastline_timeseries"]["t_s"].to_numpy())       # one time unit for the whole report
    rows, sections = [], []
    for case in cases:
        row, blocks = _orbit_report(case, tables, Path(stage), unit)
        rows.append(row)
        sections.append((f"Coastline EKF, geometric Monte Carlo (Straub & Christian Figs. 5-9): {case}", blocks))
    write_csv(Path(stage) / "summary.csv", rows)
    (Path(stage) / "table1.md").write_text(table1_markdown(rows), encoding="utf-8")
    links = {"kind": "links", "files": ["summary.csv", "table1.md"]}
    return [(title, _render(blocks + [links])) for title, blocks in sections]
