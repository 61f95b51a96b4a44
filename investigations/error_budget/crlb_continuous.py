"""The error budget's registration CRLB restated on the continuous truth over the estimator's pixels.

The published ``crlb_s``/``crlb_l`` columns of ``results/error_budget`` (and of ``results/retina_vs_spc``, the same
nominal truth render) are the finite-difference bound of the 8-spp truth pixels over a square window
(:func:`renderlab.campaign.scoring.registration_crlb`). This probe renders the budget's all-off truth twice more at
4 × 4 sub-pixels per pixel (two render seeds; :func:`renderlab.studies.retina_vs_spc.crlb_truth.fine_truth_dict`)
and takes, per landmark-frame, :func:`renderlab.campaign.crlb.continuous_crlb` over Retina's template pixels at the
true pose (:func:`~renderlab.studies.retina_vs_spc.crlb_truth.maplet_footprint`) with the budget render's sensor
variance, J the cross-product of the two fine renders (unbiased for the noise-free scene's J). Written next to this
script (small, committed):

* ``crlb_continuous.csv`` — per landmark-frame: the table's bound, the continuous bound (shift only, with gain and
  offset nuisances, from one fine render alone), the footprint's and the window's pixel counts;
* ``crlb_continuous_truth_perturbed.csv`` — the same for ``results/retina_vs_spc_truth_perturbed`` (its own scene:
  the nominal companion's truth, which also stands in for the perturbed runs' own renders);
* ``crlb_continuous.md`` — the restatement factor continuous / table per landmark-frame and axis (median, p5,
  p95), and the "× CRLB" figures of the budget's README, of ``results/retina_vs_spc`` and of the truth-perturbed
  pair recomputed from their tables with the continuous bound in place of the stored one (same statistics and
  intervals as the reports).

Usage (1 min 49 s from an empty ``--workdir`` at load 2–8, renders cached there; a rerun writes byte-identical
files)::

    OPENBLAS_NUM_THREADS=1 .venv/bin/python investigations/error_budget/crlb_continuous.py
"""

from __future__ import annotations

import argparse
import copy
import csv
import math
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
sys.path.insert(0, str(HERE))  # crlb_probe.py beside this script
K, SPP, SEEDS = 4, 32, (11, 12)


def fine_sets(truth: dict, base_dir: Path, workdir: Path):
    """The campaign's own truth render (``truth``: a scenario dict) and the two fine renders (cached)."""
    from renderlab.campaign.cache import cached_truthset
    from renderlab.files.truthset import TruthSet
    from renderlab.scenario import scenario_from_dict, truth_dict
    from renderlab.studies.retina_vs_spc.crlb_truth import fine_truth_dict

    budget = truth_dict(copy.deepcopy(truth))
    path, _ = cached_truthset(scenario_from_dict(budget, "campaign truth"), base_dir, workdir / "truth_cache")
    fine = []
    for seed in SEEDS:
        d = fine_truth_dict(budget, K)
        d["render"]["spp"], d["render"]["seed"] = SPP, seed
        p, _ = cached_truthset(scenario_from_dict(d, f"fine truth seed {seed}"), base_dir, workdir / "truth_cache")
        fine.append(TruthSet.open(p))
    return TruthSet.open(path), fine


def bounds_table(ts, fine, sensor) -> list[dict]:
    """Per landmark-frame of the budget's windows: the footprint and the continuous bounds (module docstring)."""
    from crlb_probe import windows  # the budget's CRLB windows (this folder's probe)

    from renderlab.campaign.reexpose import frame_sensor_options
    from renderlab.campaign.scoring import dn_variance, registration_crlb
    from renderlab.measurement.runner import MeasureOptions, onboard_photometry
    from renderlab.sensor.model import expected_dn
    from renderlab.studies.retina_vs_spc.crlb_truth import footprint_bound, maplet_footprint, sigma_or_nan
    from renderlab.worlds.ev5.catalog import read_catalog

    catalog = read_catalog(ts.path)
    maplets = {int(m.landmark_id): m for m in catalog}
    L_table = onboard_photometry(ts, MeasureOptions())[0]  # the onboard McEwen L(α) the methods use
    rows, per_frame = [], {}
    for (f, lid), (k, win, g) in sorted(windows(ts, catalog).items()):
        if k not in per_frame:
            o = frame_sensor_options(ts, k, sensor)
            rad = np.asarray(ts.load(k).radiance, np.float64)
            fd = [expected_dn(np.asarray(t.load(k).radiance, np.float64), o) for t in fine]
            coarse = [x.reshape(x.shape[0] // K, K, x.shape[1] // K, K).mean((1, 3)) for x in fd]
            per_frame[k] = (expected_dn(rad, o), dn_variance(rad, o), fd, coarse)
        edn, var, fd, coarse = per_frame[k]
        fp = maplet_footprint(ts.frames[k], maplets[lid], L_table)
        cross = footprint_bound(fd[0], K, var, fp, independent=fd[1])
        nuis = footprint_bound(fd[0], K, var, fp, independent=fd[1], nuisances=("gain", "offset"))
        one = footprint_bound(fd[0], K, var, fp)
        table = registration_crlb(edn[win], var[win])
        d = (coarse[0] - edn)[win]
        row = {"frame": f, "item": lid, "gsd_ratio": g, "window_px": int(edn[win].size),
               "footprint_px": 0 if cross is None else cross.pixels,
               "at_image_edge": int(fp is not None and (min(fp[0], fp[1]) < 2 or fp[0] + fp[2].shape[0] > edn.shape[0] - 2
                                                         or fp[1] + fp[2].shape[1] > edn.shape[1] - 2)),
               "table_s": table[0], "table_l": table[1]}
        for name, res in (("cont", cross), ("cont_gain_offset", nuis), ("cont_one_render", one)):
            row[f"{name}_s"], row[f"{name}_l"] = sigma_or_nan(res)
        row["fine_minus_budget_rms_dn"] = float(np.sqrt(np.mean(d * d)))
        rows.append(row)
    return rows


def _pct(x):
    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    return (float(np.median(x)), float(np.percentile(x, 5)), float(np.percentile(x, 95)), int(x.size))


def restated(rows: list[dict], folder: Path) -> list[str]:
    """The README's "× CRLB" figures with the table's and the continuous bound (same statistics as the reports)."""
    import pyarrow.parquet as pq

    from renderlab.stats import oat_budget as S
    from renderlab.studies.retina_vs_spc.budget import crlb as BC

    meas = pq.read_table(folder / "tables" / "budget_measurements.parquet")
    configs = pq.read_table(folder / "tables" / "budget_configs.parquet")
    runs = dict(zip(configs.column("config").to_pylist(), configs.column("runs").to_pylist()))
    cols = S.columns(meas)
    bound = {(r["frame"], r["item"]): (r["cont_s"], r["cont_l"]) for r in rows}
    table_same = {(r["frame"], r["item"]): (r["table_s"], r["table_l"]) if np.isfinite(r["cont_s"]) else (np.nan,) * 2
                  for r in rows}
    variants = {"table": cols, "table, same landmark-frames": BC._with_bound(cols, table_same),
                "continuous": BC._with_bound(cols, bound)}
    out = ["| method | GSD band | " + " | ".join(f"{v} (n)" for v in variants) + " |", "|---|---|---|---|---|"]
    g = cols["gsd_ratio"]
    methods = sorted(set(cols["method"]), key=lambda m: (m != "retina", m != "retina_refined", m))
    for m in methods:
        for band, lo, hi in BC.BANDS:
            mask = (g >= lo) & ((g <= hi) if band == "0.5<=gsd<=2" else (g < hi))
            cells = []
            for c in variants.values():
                r = S.noise_over_crlb(S.sample(c, "sensor_noise", m, mask, "both", runs["sensor_noise"]), 1.0)
                r = r[np.isfinite(r)]
                rng = np.random.default_rng(20)
                lo_, hi_ = S._ci(np.sqrt(np.mean(r[rng.integers(0, r.size, (1000, r.size))], 1)))
                cells.append(f"{math.sqrt(np.mean(r)):.2f} [{lo_:.2f}, {hi_:.2f}] ({r.size})")
            out.append(f"| {m} | {band} | " + " | ".join(cells) + " |")
    # the README's "median registration CRLB" (budget_summary.csv: median over a sample's rows, both axes)
    out += ["", "median bound over the rows of a configuration (both axes; README: 0.0046 px, 0.0053 for SPC):", "",
            "| config | method | table | table, same landmark-frames | continuous |", "|---|---|---|---|---|"]
    everything = np.ones(len(g), bool)
    for config in ("all_on", "all_off", "sensor_noise"):
        for m in methods:
            cells = [float(np.nanmedian(S.sample(c, config, m, everything, "both", runs[config]).crlb))
                     for c in variants.values()]
            out.append(f"| {config} | {m} | " + " | ".join(f"{v:.4f}" for v in cells) + " |")
    return out


def retina_vs_spc(rows: list[dict], folder: Path, proxy: bool = False) -> list[str]:
    """Robust σ / CRLB of a ``retina_vs_spc`` folder (the report's statistics) with the stored and the continuous
    bound of ``rows`` per landmark-frame (the nominal truth render's; with ``proxy`` the campaign's runs rendered
    their own perturbed truth, and the nominal bound stands in for each run's)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from renderlab.report.landmark_stats import method_summary

    t = pq.read_table(folder / "tables" / "measurements.parquet")
    keys = list(zip(t.column("frame").to_pylist(), t.column("item").to_pylist()))
    by = {(r["frame"], r["item"]): r for r in rows}
    old = np.array([t.column("crlb_s").to_numpy(zero_copy_only=False), t.column("crlb_l").to_numpy(zero_copy_only=False)]).T
    mine = np.array([[by[k]["table_s"], by[k]["table_l"]] if k in by else [np.nan, np.nan] for k in keys])
    ok = np.isfinite(old) & np.isfinite(mine)
    dev = np.abs(mine[ok] / old[ok] - 1)
    same = f"median {np.median(dev):.1e}, p95 {np.percentile(dev, 95):.1e}, max {dev.max():.1e}"
    cont = np.array([[by[k]["cont_s"], by[k]["cont_l"]] if k in by else [np.nan, np.nan] for k in keys])
    t2 = t.set_column(t.column_names.index("crlb_s"), "crlb_s", pa.array(cont[:, 0]))
    t2 = t2.set_column(t2.column_names.index("crlb_l"), "crlb_l", pa.array(cont[:, 1]))
    how = ("the nominal render's continuous bound stands in for each run's own perturbed truth" if proxy
           else "continuous: of the same scene rendered by today's code")
    out = [f"stored bound of {folder.name} against the finite-difference bound of today's render of its nominal "
           f"truth (same windows): relative difference {same} over {int(ok.sum())} values (the stored one is of "
           f"the campaign's own render{'s at perturbed poses' if proxy else ', made by earlier render code'}); "
           f"{how}", "",
           "| subset | method | axis | robust σ (px) | CRLB rms table (px) | robust σ / CRLB table | CRLB rms continuous "
           "(px) | robust σ / CRLB continuous |", "|---|---|---|---|---|---|---|---|"]
    from renderlab.scenario import load_scenario
    from renderlab.studies.retina_vs_spc.report import _config, well_measured_mask

    cfg = _config(load_scenario(folder / "scenario.toml")[0].to_dict())
    for subset, mask in (("all", None), ("well_measured", well_measured_mask(t, cfg))):
        a, b = method_summary(t, mask, subset=subset), method_summary(t2, mask, subset=subset)
        for r, r2 in zip(a, b):
            out.append(f"| {subset} | {r['method']} | {r['axis']} | {r['robust_sigma_px']:.4f} | {r['crlb_rms_px']:.4f} | "
                       f"{r['robust_sigma_over_crlb']:.1f} | {r2['crlb_rms_px']:.4f} | {r2['robust_sigma_over_crlb']:.1f} |")
    return out


def write_rows(path: Path, rows: list[dict]) -> None:
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})


def factor_lines(rows: list[dict]) -> list[str]:
    """The ratios per landmark-frame and axis (median, p5, p95) and the footprint/render checks, as Markdown."""
    def ratio(a, b, rs=rows):
        return [r[f"{a}_{x}"] / r[f"{b}_{x}"] for r in rs for x in "sl"]

    md = ["| ratio | median | p5 | p95 | n |", "|---|---|---|---|---|"]
    for label, a, b in (("continuous / table (the restatement factor)", "cont", "table"),
                        ("continuous with gain, offset / continuous", "cont_gain_offset", "cont"),
                        ("one fine render / cross-product of two", "cont_one_render", "cont")):
        m, p5, p95, n = _pct(ratio(a, b))
        md.append(f"| {label} | {m:.3f} | {p5:.3f} | {p95:.3f} | {n} |")
    inner = [r for r in rows if not r["at_image_edge"]]
    m, p5, p95, n = _pct(ratio("cont", "table", inner))
    md.append(f"| continuous / table, footprints ≥ 2 px from the image edge ({len(inner)} landmark-frames; at the "
              f"edge the derivatives come from a mirrored extension) | {m:.3f} | {p5:.3f} | {p95:.3f} | {n} |")
    fp = _pct([r["footprint_px"] / r["window_px"] for r in rows])
    dd = _pct([r["fine_minus_budget_rms_dn"] for r in rows])
    md += ["", f"footprint / window pixels: median {fp[0]:.2f} (p5 {fp[1]:.2f}, p95 {fp[2]:.2f}); fine render's block "
           f"means − campaign render, rms per window: median {dd[0]:.2f} DN (p5 {dd[1]:.2f}, p95 {dd[2]:.2f}; the "
           "campaign render's own Monte-Carlo noise)"]
    return md


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description="the error budget's CRLB on the continuous truth over Retina's template "
                                "pixels, against the stored finite-difference window bound")
    p.add_argument("--folder", type=Path, default=ROOT / "results" / "error_budget")
    p.add_argument("--workdir", type=Path, default=Path("/tmp/renderlab_crlb_continuous"))
    p.add_argument("--out", type=Path, default=HERE)
    args = p.parse_args(argv)
    from renderlab.scenario import load_scenario
    from renderlab.sensor.model import SensorOptions
    from renderlab.studies.retina_vs_spc.budget.plan import budget_configs

    scenario, base_dir = load_scenario(args.folder / "scenario.toml")
    all_off = next(c for c in budget_configs(scenario.to_dict()) if c["config"] == "all_off")["scenario"]
    ts, fine = fine_sets(all_off, Path(base_dir), args.workdir)
    rows = bounds_table(ts, fine, SensorOptions(**scenario.sensor.options_dict()))
    md = ["# The error budget's CRLB on the continuous truth (`crlb_continuous.py`)", "",
          f"{len(rows)} landmark-frames of the budget's all-off truth; fine renders {K}×{K} sub-pixels, {SPP} spp "
          f"each, seeds {SEEDS}. Per landmark-frame and axis:", ""]
    md += factor_lines(rows)
    md += ["", "## Error budget: sensor noise alone, rms of noise sd / CRLB", ""]
    md += restated(rows, args.folder)
    md += ["", "## results/retina_vs_spc: robust σ / CRLB rms", ""]
    md += retina_vs_spc(rows, args.folder.parent / "retina_vs_spc")
    write_rows(args.out / "crlb_continuous.csv", rows)
    # the truth-perturbed pair: its own scene (2 frames, 128 px); the nominal companion's render
    tp = args.folder.parent / "retina_vs_spc_truth_perturbed"
    sc2, base2 = load_scenario(tp / "nominal" / "scenario.toml")
    ts2, fine2 = fine_sets(sc2.to_dict(), Path(base2), args.workdir)
    rows2 = bounds_table(ts2, fine2, SensorOptions(**sc2.sensor.options_dict()))
    write_rows(args.out / "crlb_continuous_truth_perturbed.csv", rows2)
    md += ["", "## results/retina_vs_spc_truth_perturbed (its own scene: the nominal companion's truth render)", "",
           f"{len(rows2)} landmark-frames.", ""]
    md += factor_lines(rows2)
    md += ["", "### nominal/ (the continuous bound of the same render)", ""]
    md += retina_vs_spc(rows2, tp / "nominal")
    md += ["", "### the perturbed campaign (each run its own truth render; the nominal render's continuous bound "
           "per landmark-frame stands in for it)", ""]
    md += retina_vs_spc(rows2, tp, proxy=True)
    (args.out / "crlb_continuous.md").write_text("\n".join(md) + "\n")
    print("\n".join(md))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
