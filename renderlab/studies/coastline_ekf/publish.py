"""Publish the geometric coastline-EKF Monte Carlo (Straub & Christian Table 1, Figs. 5-9) into a folder, and its
published layout: ``campaign.json``, ``runs.json`` and the per-orbit tables (:data:`TABLES`, each with a ``case``
column) from which ``renderlab report FOLDER`` regenerates the whole report, with no re-run.

    python -m renderlab.studies.coastline_ekf.publish --out results/coastline_ekf --runs 1000 --orbits all

``--keep-runs`` also hands every run's rows to :func:`publish_tables` (the layout: docs/coastline_ekf.md).
"""

from __future__ import annotations

import argparse
import json
import math
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from renderlab.campaign import compact, store
from renderlab.campaign.publish import published_tables
from renderlab.errors import UserError, run_main
from renderlab.report.campaign_report import make_report, render_blocks
from renderlab.report.csvio import write_csv
from renderlab.studies.coastline_ekf.figures import time_unit
from renderlab.studies.coastline_ekf.geometric import (
    FILTER_COLUMNS,
    PAPER_ORBITS,
    paper_orbit,
    run_batch,
    truth_geometry,
)
from renderlab.studies.coastline_ekf.report_section import summary_blocks
from renderlab.studies.coastline_ekf.scoring import ERR, SIG, _columns, nis_band_test, pcrb_ric_sigma, per_time_summary

__all__ = ["TABLES", "orbit_tables", "sample_table", "write_folder", "is_geometric", "report_sections", "PAPER_TABLE1",
           "publish_tables", "main"]

TABLES = ("coastline_orbits", "coastline_timeseries", "coastline_run_totals", "coastline_sample_runs", "coastline_runs")
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
    """The published tables of orbit ``case`` (names of :data:`TABLES`) from its options, truth geometry, every
    run's filter rows, their :func:`.scoring.per_time_summary` (with the PCRB σ) and the wall ``seconds``
    (``geometry``, ``monte_carlo``); ``keep_runs``: also every run's rows (``coastline_runs``)."""
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


def write_folder(out: Path, parts: list[dict], manifest: dict) -> None:
    """Write ``campaign.json``, ``runs.json`` and ``tables/`` (the orbits' tables concatenated, reduced by
    :func:`publish_tables`, the full ones recorded in ``raw_tables.json``) into ``out``; other entries of ``out``
    (README, report) are kept."""
    import pyarrow as pa

    names = [n for n in TABLES if any(n in p for p in parts)]
    with store.staged_folder(Path(out), "the published study") as stage:
        (stage / "tables").mkdir()
        raw = {n: pa.concat_tables([p[n] for p in parts if n in p]) for n in names}
        for n, t in published_tables(manifest, raw, stage / "tables").items():
            compact.write_compact(t, stage / "tables" / f"{n}.parquet")
        (stage / "campaign.json").write_text(json.dumps(manifest, indent=1, sort_keys=True) + "\n", encoding="utf-8")
        store.write_statuses(stage, manifest, [{"run": i, "status": "ok", "error": "", "tables": names}
                                               for i in range(manifest["plan"]["runs"])])


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
        summary, sample = _from_runs(summary, _case(tables["coastline_runs"], case))
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


def _from_runs(summary, runs):
    """(per-time summary, sample drawn) of one orbit's every-run rows; the PCRB σ taken from its ``summary``."""
    pcrb = [s.replace("sig_", "pcrb_sig_") for s in SIG]
    has = all(p in summary.column_names for p in pcrb)
    return (per_time_summary(runs, np.stack([summary[p].to_numpy() for p in pcrb], axis=1) if has else None),
            _first_runs(runs.select(["run", "t_s", *ERR])))


def publish_tables(tables: dict) -> dict:
    """What a published coastline folder ships (:attr:`renderlab.contracts.study.Study.publish_tables`): the tables
    as the report reads them. Filter tables keep :data:`FILTER_COLUMNS` (frames tables stay whole: the image README
    quotes their per-image counts); in the geometric layout every run's rows become what the report makes of them (per-time summary, the sample
    drawn), the per-run NIS totals one sum per orbit (the report adds them up) and the summary loses the run means."""
    import pyarrow as pa

    out = {}
    for name, t in tables.items():
        out[name] = t.select([c for c in t.column_names if c in FILTER_COLUMNS]) if name.endswith("_filter") else t
    if not is_geometric(tables):
        return out
    cases = list(dict.fromkeys(tables["coastline_orbits"]["case"].to_pylist()))
    if "coastline_runs" in out:
        ts, runs = out["coastline_timeseries"], out.pop("coastline_runs")
        made = [_from_runs(_case(ts, c), _case(runs, c)) for c in cases]
        out["coastline_timeseries"] = pa.concat_tables([_with_case(s, c) for c, (s, _) in zip(cases, made)])
        out["coastline_sample_runs"] = pa.concat_tables([_with_case(r, c) for c, (_, r) in zip(cases, made)])
    ts = out["coastline_timeseries"]
    out["coastline_timeseries"] = ts.select([c for c in ts.column_names if not c.startswith("mc_mean_")])
    tot = out["coastline_run_totals"]
    if "run" in tot.column_names:
        sums = {k: [float(np.sum(_case(tot, c)[k].to_numpy())) for c in cases] for k in ("nis_sum", "nis_dof")}
        out["coastline_run_totals"] = pa.table({"case": cases, **sums})
    return out


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
    return [(title, render_blocks(blocks + [links])) for title, blocks in sections]


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m renderlab.studies.coastline_ekf.publish", description=__doc__.split("\n")[0])
    p.add_argument("--out", required=True, type=Path)
    p.add_argument("--runs", type=int, default=1000)
    p.add_argument("--orbits", default="all", help="comma list of i00_h1000,i45_h1000,i90_h1000,i45_h500,i90_h500")
    p.add_argument("--seed", type=int, default=2026)
    p.add_argument("--revolutions", type=float, default=1.0, help="duration in orbital periods")
    p.add_argument("--cadence-s", type=float, default=30.0)
    p.add_argument("--sigma-theta-mrad", type=float, default=0.5)
    p.add_argument("--points-per-image", type=int, default=16)
    p.add_argument("--chunk", type=int, default=250, help="runs per vectorised batch (memory)")
    p.add_argument("--keep-runs", action="store_true")
    p.add_argument("--truth-model", choices=["j2_rk4", "zonal_dop853"], default="j2_rk4",
                   help="truth propagator: the filter's class of model (default) or DOP853 with zonals J2..J6")
    p.add_argument("--zonal-degree", type=int, default=6, help="zonal_dop853: highest zonal degree")
    return p


def publish_orbit(case: str, args) -> dict:
    """Run one orbit's Monte Carlo → its published tables (:func:`orbit_tables`)."""
    import pyarrow as pa

    o = paper_orbit(case, cadence_s=args.cadence_s, sigma_theta_rad=args.sigma_theta_mrad * 1e-3,
                    points_per_image=args.points_per_image)
    o = replace(o, duration_s=args.revolutions * o.period_s).validate()
    if getattr(args, "truth_model", "j2_rk4") != "j2_rk4":
        o = replace(o, truth_model=args.truth_model, zonal_degree=args.zonal_degree)
    t0 = time.perf_counter()
    geo = truth_geometry(o)
    t_geo = time.perf_counter() - t0
    seeds = np.random.SeedSequence([args.seed, list(PAPER_TABLE1).index(case)]).spawn(args.runs)
    t0 = time.perf_counter()
    parts = [run_batch(o, seeds[a:a + args.chunk], range(a, min(a + args.chunk, args.runs)), progress=True)["table"]
             for a in range(0, args.runs, args.chunk)]
    t_mc = time.perf_counter() - t0
    table = pa.concat_tables(parts)
    summary = per_time_summary(table, pcrb_ric_sigma(geo, o))
    return orbit_tables(case, o, geo, table, summary, {"geometry": t_geo, "monte_carlo": t_mc}, args.keep_runs)


def _manifest(args, cases: list[str]) -> dict:
    """``campaign.json``: the plan is the command's options (the scenario of every orbit)."""
    opts = {k: v for k, v in sorted(vars(args).items()) if k not in ("out", "chunk", "orbits")}
    name = "coastline_ekf_geometric" + ("" if args.out.name == "coastline_ekf" else f"_{args.out.name}")
    scenario = {"description": "geometric coastline-EKF Monte Carlo, Straub & Christian Table 1",
                "world": {"kind": "earth"}, "trajectory": {"kind": "leo"}, "orbits": cases, "options": opts,
                "perturbations": {"apriori_position_sigma_m": [500.0] * 3, "apriori_velocity_sigma_mps": [0.005] * 3}}
    seed = {"entropy": args.seed, "run_seed": "SeedSequence([entropy, orbit index]).spawn(runs)[run]"}
    return {"format": "renderlab.campaign/1", "name": name, "versions": store._versions(),
            "plan": {"study": "coastline_ekf", "runs": args.runs, "scenario": scenario, "seed": seed}}


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    cases = list(PAPER_ORBITS) if args.orbits == "all" else [c.strip() for c in args.orbits.split(",")]
    bad = [c for c in cases if c not in PAPER_ORBITS]
    if bad or args.runs < 1 or args.chunk < 1:
        raise UserError(f"unknown orbit {bad[0]!r}; choose from {', '.join(PAPER_ORBITS)}" if bad
                        else "--runs and --chunk must be >= 1")
    parts = [publish_orbit(c, args) for c in cases]
    write_folder(args.out, parts, _manifest(args, cases))
    page = make_report(args.out, args.out / "report")
    print((args.out / "report" / "table1.md").read_text())
    print(f"published {args.out} (tables/, campaign.json, runs.json); report {page}")
    return 0


if __name__ == "__main__":
    raise SystemExit(run_main(main))
