"""Is the error budget's registration CRLB biased by the Monte-Carlo noise of its truth render? (:mod:`.runner`)

The published budget's CRLB per landmark-frame (``crlb_s``/``crlb_l``, made by :func:`.run.landmark_extras` before
it took the continuous bound of :mod:`renderlab.campaign.crlb`; restated in
``investigations/error_budget/crlb_continuous.py``) is :func:`renderlab.campaign.scoring.registration_crlb` of the
truth image's expected DN over a square window around the landmark, J = Σ w ∇I ∇Iᵀ with w = 1/σ² the sensor's DN variance. The truth image is a render at
``render.spp`` (8) random sub-pixel samples per pixel: the box-filtered radiance plus zero-mean render noise ε,
independent between pixels. The gradients of one render then carry the noise's energy too,
E[∇I ∇Iᵀ] = ∇Ī ∇Īᵀ + Cov(∇ε), so J is overstated and the bound understated — the more so where the terrain
varies inside a pixel. The render noise is part of the fixed truth image of every run (the runs re-expose the
same radiance), so it is a per-landmark *bias* of the estimators, not noise; the bound their run-to-run noise
must be compared with is that of the noise-free image Ī, with the sensor's variance.

This probe renders the budget's all-off truth (the ``all_off`` configuration's world, sensor and camera) again
with other render seeds and more samples, cuts the budget's windows from each and estimates J four ways:

* ``budget`` — one render at the scenario's spp and seed: the budget's own bound (reproduces its columns);
* ``second`` — one render at the same spp, another seed;
* ``cross`` — the cross-product of those two, Σ w (∇I¹ ∇I²ᵀ + ∇I² ∇I¹ᵀ)/2: unbiased for the noise-free J
  since the two renders' noises are independent (``registration_crlb(..., independent=...)``);
* ``high_a`` / ``high_b`` — one render at each high spp (render bias down by the spp ratio);
* ``clean`` — the cross-product of the two high-spp renders: the reference;
* ``footprint`` — the bound of the ``high_b`` image over the pixels Retina's template covers (its ray-traced
  prediction from the exact maplet at the true pose, k = 3, the fitted McEwen L(α); pixels with ±2 valid
  neighbours along both axes) instead of the budget's square window;
* ``template`` — over the same pixels, the noise a shift estimator matching that template (gain and offset
  fitted) would have: the sandwich H⁻¹ B H⁻ᵀ of :func:`renderlab.campaign.scoring.template_shift_covariance`,
  H = Σ w ∇t ∇Iᵀ, B = Σ w ∇t ∇tᵀ (equal to ``footprint`` when the template is the image). The measured noise sd
  over it near 1 says the template–truth mismatch accounts for the noise beyond the bound.

The variance w is the sensor's at the budget render's radiance with its exposure (the noise the budget's
runs saw) in every estimate. The rows go to ``tables/budget_crlb.parquet`` (one per landmark-frame and
estimate); :func:`report_rows` turns them and the budget's sensor-noise-alone rows into the rms noise sd /
CRLB with the budget's bound and with the clean one (``report/budget_crlb.csv``)::

    python -m renderlab.studies.retina_vs_spc.budget.crlb results/error_budget
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

from estimators.retina import CameraPoseEstimate, TemplateOptions, build_mesh, render_template
from renderlab.campaign.cache import cached_truthset
from renderlab.campaign.oat_tables import TABLES
from renderlab.campaign.reexpose import frame_sensor_options
from renderlab.campaign.scoring import dn_variance, image_gradients, registration_crlb, template_shift_covariance
from renderlab.errors import UserError
from renderlab.files.truthset import TruthSet
from renderlab.geometry.camera import CameraModel
from renderlab.geometry.rotations import rotation_from_quat_xyzw
from renderlab.measurement.runner import MeasureOptions, onboard_photometry
from renderlab.scenario import load_scenario, scenario_from_dict, truth_dict
from renderlab.sensor.model import SensorOptions, expected_dn
from renderlab.stats import oat_budget as S
from renderlab.studies.retina_vs_spc.budget.plan import BUDGET_TABLES, budget_configs
from renderlab.worlds.ev5.catalog import read_catalog

TABLE = "budget_crlb"
ESTIMATES = ("budget", "second", "cross", "high_a", "high_b", "clean", "footprint", "template")
BANDS = (("all", 0.0, np.inf), ("gsd<0.5", 0.0, 0.5), ("0.5<=gsd<=2", 0.5, 2.0), ("gsd>2", 2.0, np.inf))


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
    """{(frame, landmark_id): (frame position, (row slice, column slice))} — the CRLB windows of the published
    budget's finite-difference bound (half-size ½·(maplet size − 1)/GSD ratio, ≥ 3 px, clipped; ≥ 7 px each way)."""
    truth = ts.read_table("landmark_truth").to_pydict()
    by_id = {int(m.landmark_id): m for m in maplets}
    index_of = {int(rec["index"]): k for k, rec in enumerate(ts.frames)}
    H, W = int(ts.frames[0]["camera"]["height"]), int(ts.frames[0]["camera"]["width"])
    out = {}
    for f, lid, s, l, g in zip(truth["frame"], truth["landmark_id"], truth["s"], truth["l"], truth["gsd_ratio"]):
        m, k = by_id.get(int(lid)), index_of.get(int(f))
        if m is None or k is None or not (np.isfinite(s) and np.isfinite(l) and g is not None and np.isfinite(g)
                                          and g > 0):
            continue
        half = int(max(3, math.ceil(0.5 * (m.heights_m.shape[0] - 1) / g)))
        c0, r0 = int(round(s)), int(round(l))
        win = (slice(max(r0 - half, 0), min(r0 + half + 1, H)), slice(max(c0 - half, 0), min(c0 + half + 1, W)))
        if min(win[0].stop - win[0].start, win[1].stop - win[1].start) >= 7:
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


def onboard_L_table(ts) -> tuple:
    """The onboard McEwen L(α) fitted to the truth set's law (what the budget's methods use)."""
    return onboard_photometry(ts, MeasureOptions())[0]


def template_match(ts, k: int, maplet, clean: np.ndarray, variance: np.ndarray, L_table: tuple) -> dict:
    """:func:`renderlab.campaign.scoring.template_shift_covariance` of Retina's template of ``maplet`` (exact
    maplet, true camera, pose and Sun of frame ``k``, k = 3 samples per pixel) against the ``clean`` image."""
    rec = ts.frames[k]
    R = rotation_from_quat_xyzw(rec["pose"]["quat_render_from_cam_xyzw"], "pose").as_matrix()
    sun = np.asarray(rec["sun"]["direction_render"], float)
    tpl = render_template(build_mesh(maplet), CameraModel.from_dict(rec["camera"]),
                          CameraPoseEstimate(R, np.asarray(rec["pose"]["position_m"], float)), sun / np.linalg.norm(sun),
                          TemplateOptions(supersample=3, L_table=tuple(L_table)))
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
    import pyarrow as pa


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
    L_table = onboard_L_table(ts)
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


# ------------------------------------------------------------------------------------ report (tables alone)
def _noise_row(table) -> dict:
    """Medians over landmark-frames of the window diagnostics (:func:`window_noise`) and of the CRLB ratio they
    predict for one low-spp render, √(g² / (g² + (130/144)·σ_render²)) (pixel-independent render noise)."""
    d = table.to_pydict()
    sel = np.array([e == "budget" for e in d["estimate"]])
    r, s, g = (np.asarray(d[c], float)[sel] for c in ("render_sd_dn", "sensor_sd_dn", "gradient_rms_dn"))
    pred = np.sqrt(g * g / (g * g + 130 / 144 * r * r))
    return {"kind": "window_noise", "estimate": "budget", "n": int(sel.sum()),
            "render_sd_dn": float(np.median(r)), "sensor_sd_dn": float(np.median(s)),
            "gradient_rms_dn": float(np.median(g)), "predicted_ratio": float(np.median(pred))}


def _bounds(table) -> dict:
    """{estimate: {(frame, item): (crlb_s, crlb_l)}} of a probe table."""
    d = table.to_pydict()
    out = {e: {} for e in ESTIMATES}
    for f, i, e, s, l in zip(d["frame"], d["item"], d["estimate"], d["crlb_s"], d["crlb_l"]):
        out.setdefault(e, {})[(int(f), int(i))] = (float(s), float(l))
    return out


def _with_bound(cols: dict, bound: dict) -> dict:
    """``cols`` (:func:`renderlab.stats.oat_budget.columns`) with ``crlb_s``/``crlb_l`` replaced by ``bound`` per landmark-frame
    (NaN where the probe has none)."""
    out = dict(cols)
    keys = list(zip(cols["frame"].tolist(), cols["item"].tolist()))
    vals = np.array([bound.get(k, (np.nan, np.nan)) for k in keys], float).reshape(-1, 2)
    out["crlb_s"], out["crlb_l"] = vals[:, 0], vals[:, 1]
    return out


def _ratio_rows(bounds: dict) -> list[dict]:
    """Per estimate: the per landmark-frame and axis ratio CRLB(estimate) / CRLB(clean), its percentiles."""
    clean = bounds["clean"]
    out = []
    for est in ESTIMATES:
        if est == "clean":
            continue
        r = np.array([bounds[est][k][a] / clean[k][a] for k in clean if k in bounds[est] for a in (0, 1)], float)
        r = r[np.isfinite(r) & (r > 0)]
        if r.size:
            p = np.percentile(r, [5, 25, 50, 75, 95])
            out.append({"kind": "crlb_ratio", "estimate": est, "over": "clean", "n": int(r.size),
                        **dict(zip(("p5", "p25", "median", "p75", "p95"), map(float, p))),
                        "rms": float(np.sqrt(np.mean(r * r)))})
    return out


def report_rows(meas, configs, probe, gross_px: float = 1.0, n_boot: int = 1000, seed: int = 20) -> list[dict]:
    """Rows of ``report/budget_crlb.csv``: the CRLB ratios (:func:`_ratio_rows`) and, per method and GSD band,
    the sensor-noise-alone rms noise sd / CRLB with the budget's bound (the table's columns) and with each probe
    estimate (interval: resampling the per landmark-frame-axis ratios, as in :func:`renderlab.stats.oat_budget.summary_row`)."""
    bounds = _bounds(probe)
    out = _ratio_rows(bounds) + [_noise_row(probe)]
    runs = dict(zip(configs.column("config").to_pylist(), configs.column("runs").to_pylist()))
    if runs.get("sensor_noise", 0) < 2:
        return _uniform(out)
    cols = S.columns(meas)
    variants = {"table": cols, **{e: _with_bound(cols, bounds[e]) for e in ("budget", "cross", "high_b", "clean",
                                                                            "footprint", "template")}}
    methods = sorted(set(cols["method"]), key=lambda m: (m != "retina", m != "retina_refined", m))
    g = cols["gsd_ratio"]
    for m in methods:
        for band, lo, hi in BANDS:
            mask = (g >= lo) & ((g <= hi) if band == "0.5<=gsd<=2" else (g < hi))
            for est, c in variants.items():
                r = S.noise_over_crlb(S.sample(c, "sensor_noise", m, mask, "both", runs["sensor_noise"]), gross_px)
                r = r[np.isfinite(r)]
                row = {"kind": "noise_over_crlb", "estimate": est, "method": m, "band": band, "n": int(r.size),
                       "value": float(np.sqrt(np.mean(r))) if r.size else math.nan, "lo": math.nan, "hi": math.nan}
                if r.size >= 10:
                    rng = np.random.default_rng(seed)
                    row["lo"], row["hi"] = S._ci(np.sqrt(np.mean(r[rng.integers(0, r.size, (n_boot, r.size))], 1)))
                out.append(row)
    return _uniform(out)


def _uniform(rows: list[dict]) -> list[dict]:
    """Every row with every key (one CSV header; absent values empty)."""
    keys = list(dict.fromkeys(k for r in rows for k in r))
    return [{k: r.get(k, "") for k in keys} for r in rows]


def read_probe(folder: Path):
    """The probe table of a budget folder, or None when it has none."""
    import pyarrow.parquet as pq


    p = Path(folder) / TABLES / f"{TABLE}.parquet"
    return pq.read_table(p) if p.is_file() else None


def markdown(rows: list[dict]) -> str:
    """The report's section: CRLB ratios and the noise / CRLB with each bound (both axes pooled)."""
    out = ["### the CRLB of the 8-spp truth render against a clean one (per landmark-frame and axis)", "",
           "| estimate | n | p5 | p25 | median | p75 | p95 |", "|---|---|---|---|---|---|---|"]
    out += [f"| {r['estimate']} / clean | {r['n']} | {r['p5']:.3f} | {r['p25']:.3f} | {r['median']:.3f} | "
            f"{r['p75']:.3f} | {r['p95']:.3f} |" for r in rows if r["kind"] == "crlb_ratio"]
    w = next((r for r in rows if r["kind"] == "window_noise"), None)
    if w:
        out += ["", f"Over the windows (median of {w['n']} landmark-frames): render-noise sd of one low-spp render "
                f"{w['render_sd_dn']:.2f} DN, sensor-noise sd {w['sensor_sd_dn']:.2f} DN, clean gradient rms "
                f"{w['gradient_rms_dn']:.1f} DN/px; predicted CRLB ratio √(g²/(g² + (130/144)·σ²)) "
                f"{w['predicted_ratio']:.3f}."]
    nr = [r for r in rows if r["kind"] == "noise_over_crlb"]
    if nr:
        ests = list(dict.fromkeys(r["estimate"] for r in nr))
        out += ["", "### sensor noise alone: rms of noise sd / CRLB with each bound (both axes pooled)", "",
                "| method | GSD band | " + " | ".join(ests) + " |", "|---|---|" + "---|" * len(ests)]
        for m, band in dict.fromkeys((r["method"], r["band"]) for r in nr):
            cells = []
            for e in ests:
                r = next(x for x in nr if x["method"] == m and x["band"] == band and x["estimate"] == e)
                cells.append(f"{r['value']:.2f} [{r['lo']:.2f}, {r['hi']:.2f}]" if np.isfinite(r["value"]) else "–")
            out.append(f"| {m} | {band} | " + " | ".join(cells) + " |")
    return "\n".join(out) + "\n"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m renderlab.studies.retina_vs_spc.budget.crlb",
                                description="the budget's CRLB from its 8-spp truth render against clean renders")
    p.add_argument("folder", type=Path, help="an error-budget folder (its tables/ get budget_crlb.parquet)")
    p.add_argument("--scenario", type=Path, default=None, help="base scenario (default: FOLDER/scenario.toml)")
    p.add_argument("--workdir", type=Path, default=Path("/tmp/renderlab_error_budget"), help="scratch (truth cache)")
    p.add_argument("--high-spp", type=int, nargs=2, default=list(CrlbProbeOptions().high_spp))
    args = p.parse_args(argv)
    try:
        import pyarrow.parquet as pq


        BUDGET_TABLES.read(args.folder)  # a budget folder, before anything renders
        if min(args.high_spp) < 1:
            raise UserError(f"--high-spp must be positive, got {args.high_spp}")
        scenario, base_dir = load_scenario(args.scenario or args.folder / "scenario.toml")
        all_off = next(c for c in budget_configs(scenario.to_dict()) if c["config"] == "all_off")["scenario"]
        table = probe_table(all_off, base_dir, args.workdir, CrlbProbeOptions(high_spp=tuple(args.high_spp)))
        out = Path(args.folder) / TABLES / f"{TABLE}.parquet"
        tmp = out.with_name(f".{out.name}.tmp")
        pq.write_table(table, tmp)
        tmp.replace(out)
        print(f"renderlab: wrote {out} ({table.num_rows} rows)")
    except UserError as err:
        print(f"renderlab: error: {err}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
