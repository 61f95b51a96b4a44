"""Is the error budget's registration CRLB biased by the Monte-Carlo noise of its truth render? The budget's all-off
truth rendered again with other seeds and more samples, the bound estimated per landmark-frame and estimate
(``budget``, ``second``, ``cross``, ``high_a``, ``high_b``, ``clean``, ``footprint``, ``template``; the derivation:
``docs/retina_vs_spc.md``) into ``tables/budget_crlb.parquet`` of a budget folder; the budget's report reads it
(:mod:`renderlab.studies.retina_vs_spc.budget.crlb`: ``report/budget_crlb.csv``)::

    OPENBLAS_NUM_THREADS=1 .venv/bin/python investigations/error_budget/crlb_probe.py results/error_budget
    .venv/bin/renderlab report results/error_budget
"""

from __future__ import annotations

import argparse
import copy
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa

from renderlab.campaign.cache import cached_truthset
from renderlab.campaign.crlb import crlb_window
from renderlab.campaign.oat_tables import TABLES
from renderlab.campaign.reexpose import frame_sensor_options
from renderlab.campaign.scoring import dn_variance, image_gradients, registration_crlb, template_shift_covariance
from renderlab.errors import UserError
from renderlab.files.parquet_compact import write_compact_replacing
from renderlab.files.truthset import TruthSet
from renderlab.measurement.runner import MeasureOptions, onboard_photometry
from renderlab.scenario import load_scenario, scenario_from_dict, truth_dict
from renderlab.sensor.model import SensorOptions, expected_dn
from renderlab.studies.retina_vs_spc.budget.crlb import ESTIMATES, TABLE
from renderlab.studies.retina_vs_spc.budget.plan import BUDGET_TABLES, budget_configs
from renderlab.studies.retina_vs_spc.crlb_truth import true_template
from renderlab.worlds.ev5.catalog import read_catalog


@dataclass(frozen=True)
class CrlbProbeOptions:
    """Renders of the probe: the second low-spp render's seed offset, the two high-spp counts."""

    high_spp: tuple[int, int] = (256, 4096)
    seed_offset: int = 1  # render seeds: budget's s, then s + 1, s + 2, s + 3


def _truth_scenario(all_off: dict, spp: int | None, seed: int):
    d = truth_dict(copy.deepcopy(all_off))
    if spp is not None:
        d["render"]["spp"] = int(spp)
    d["render"]["seed"] = int(seed)
    return scenario_from_dict(d, f"error budget all_off truth (spp {d['render']['spp']}, seed {seed})")


def windows(ts, maplets) -> dict:
    """{(frame, landmark_id): (frame position, (row slice, column slice), GSD ratio)} — the CRLB windows of the
    published budget's finite-difference bound (:func:`renderlab.campaign.crlb.crlb_window`)."""
    truth = ts.read_table("landmark_truth").to_pydict()
    by_id = {int(m.landmark_id): m for m in maplets}
    index_of = {int(rec["index"]): k for k, rec in enumerate(ts.frames)}
    shape = (int(ts.frames[0]["camera"]["height"]), int(ts.frames[0]["camera"]["width"]))
    out = {}
    for f, lid, s, l, g in zip(truth["frame"], truth["landmark_id"], truth["s"], truth["l"], truth["gsd_ratio"]):
        m, k = by_id.get(int(lid)), index_of.get(int(f))
        win = None if m is None or k is None else crlb_window(s, l, g, m.heights_m.shape[0], shape)
        if win is not None:
            out[(int(f), int(lid))] = (k, win, float(g))
    return out


def window_noise(low_a: np.ndarray, low_b: np.ndarray, clean: np.ndarray, variance: np.ndarray) -> tuple:
    """(render-noise sd of one low-spp render, from the difference of two: rms(a − b)/√2; sensor noise sd,
    rms of √variance; rms of the clean image's gradient per axis, the stencil's) over a window, DN."""
    gs, gl = image_gradients(np.asarray(clean, float))
    g = np.concatenate([gs[np.isfinite(gs)], gl[np.isfinite(gl)]])
    d = np.asarray(low_a, float) - np.asarray(low_b, float)
    return (float(np.sqrt(np.mean(d * d) / 2)), float(np.sqrt(np.mean(variance))),
            float(np.sqrt(np.mean(g * g))) if g.size else math.nan)


def template_match(ts, k: int, maplet, clean: np.ndarray, variance: np.ndarray, L_table: tuple) -> dict:
    """:func:`renderlab.campaign.scoring.template_shift_covariance` of Retina's template of ``maplet`` (exact
    maplet, true camera, pose and Sun of frame ``k``, k = 3 samples per pixel) against the ``clean`` image."""
    tpl = true_template(ts.frames[k], maplet, L_table)[0]
    none = {"sandwich": (math.nan, math.nan), "crlb": (math.nan, math.nan), "rho": (math.nan, math.nan), "pixels": 0}
    if tpl is None:
        return none
    h, w = tpl.image.shape
    if tpl.l0 < 0 or tpl.s0 < 0 or tpl.l0 + h > clean.shape[0] or tpl.s0 + w > clean.shape[1]:
        return none  # partly outside the image
    sl = (slice(tpl.l0, tpl.l0 + h), slice(tpl.s0, tpl.s0 + w))
    return template_shift_covariance(tpl.image, clean[sl], variance[sl], tpl.valid)


def probe_table(all_off: dict, base_dir: Path, workdir: Path, opts: CrlbProbeOptions = CrlbProbeOptions()):
    """Render the all-off truth four times (module docstring) and return the per-landmark-frame estimates."""
    sc = scenario_from_dict(all_off, "error budget all_off")
    seed, spp = int(sc.render.seed), int(sc.render.spp)
    specs = [("budget", None, seed), ("second", None, seed + opts.seed_offset),
             ("high_a", opts.high_spp[0], seed + 2 * opts.seed_offset),
             ("high_b", opts.high_spp[1], seed + 3 * opts.seed_offset)]
    sets = {}
    for name, n, s in specs:
        path, _ = cached_truthset(_truth_scenario(all_off, n, s), Path(base_dir), Path(workdir) / "truth_cache")
        sets[name] = (TruthSet.open(path), n or spp, s)
    ts = sets["budget"][0]
    sensor = SensorOptions(**sc.sensor.options_dict())
    catalog = read_catalog(ts.path)
    wins = windows(ts, catalog)
    dn, var = {}, {}
    for k in range(len(ts)):
        o = frame_sensor_options(ts, k, sensor)  # the budget render's exposure, for every render
        rad = np.asarray(ts.load(k).radiance, np.float64)
        var[k] = dn_variance(rad, o)
        for name, (t, _, _) in sets.items():
            dn[name, k] = expected_dn(np.asarray(t.load(k).radiance, np.float64), o)
    pairs = {"budget": ("budget", None), "second": ("second", None), "cross": ("budget", "second"),
             "high_a": ("high_a", None), "high_b": ("high_b", None), "clean": ("high_a", "high_b")}
    rows = {c: [] for c in ("frame", "item", "gsd_ratio", "window_px", "estimate", "spp_a", "seed_a", "spp_b",
                            "seed_b", "crlb_s", "crlb_l", "render_sd_dn", "sensor_sd_dn", "gradient_rms_dn",
                            "template_px", "template_rho_s", "template_rho_l")}
    maplets = {int(m.landmark_id): m for m in catalog}
    L_table = onboard_photometry(ts, MeasureOptions())[0]  # the onboard McEwen L(α) the methods use
    for (f, lid), (k, win, g) in sorted(wins.items()):
        diag = window_noise(dn["budget", k][win], dn["second", k][win], dn["high_b", k][win], var[k][win])
        tm = template_match(ts, k, maplets[lid], dn["high_b", k], var[k], L_table)
        for est in ESTIMATES:
            a, b = pairs.get(est, ("high_b", None))
            if est in pairs:
                c = registration_crlb(dn[a, k][win], var[k][win], independent=None if b is None else dn[b, k][win])
            else:
                c = tm["crlb" if est == "footprint" else "sandwich"]
            vals = (f, lid, g, int(dn[a, k][win].size), est, sets[a][1], sets[a][2],
                    sets[b][1] if b else -1, sets[b][2] if b else -1, float(c[0]), float(c[1]), *diag,
                    int(tm["pixels"]), float(tm["rho"][0]), float(tm["rho"][1]))
            for col, v in zip(rows, vals):
                rows[col].append(v)
    types = {"frame": pa.int64(), "item": pa.int64(), "window_px": pa.int64(), "estimate": pa.string(),
             "spp_a": pa.int64(), "seed_a": pa.int64(), "spp_b": pa.int64(), "seed_b": pa.int64()}
    return pa.table({c: pa.array(v, types.get(c, pa.float64())) for c, v in rows.items()})


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description="the budget's CRLB from its 8-spp truth render against clean renders")
    p.add_argument("folder", type=Path, help="an error-budget folder (its tables/ get budget_crlb.parquet)")
    p.add_argument("--scenario", type=Path, default=None, help="base scenario (default: FOLDER/scenario.toml)")
    p.add_argument("--workdir", type=Path, default=Path("/tmp/renderlab_error_budget"), help="scratch (truth cache)")
    p.add_argument("--high-spp", type=int, nargs=2, default=list(CrlbProbeOptions().high_spp))
    args = p.parse_args(argv)
    try:
        BUDGET_TABLES.read(args.folder)  # a budget folder, before anything renders
        if min(args.high_spp) < 1:
            raise UserError(f"--high-spp must be positive, got {args.high_spp}")
        scenario, base_dir = load_scenario(args.scenario or args.folder / "scenario.toml")
        all_off = next(c for c in budget_configs(scenario.to_dict()) if c["config"] == "all_off")["scenario"]
        table = probe_table(all_off, base_dir, args.workdir, CrlbProbeOptions(high_spp=tuple(args.high_spp)))
        out = Path(args.folder) / TABLES / f"{TABLE}.parquet"
        write_compact_replacing(table, out)
        print(f"renderlab: wrote {out} ({table.num_rows} rows)")
    except UserError as err:
        print(f"renderlab: error: {err}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
