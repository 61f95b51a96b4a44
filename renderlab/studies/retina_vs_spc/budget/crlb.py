"""The error budget's CRLB probe in its report: ``tables/budget_crlb.parquet`` (the all-off truth rendered again
with other seeds and more samples, the bound per landmark-frame and :data:`ESTIMATES`; made by
``investigations/error_budget/crlb_probe.py``, the derivation in ``docs/retina_vs_spc.md``) turned with the
sensor-noise-alone rows into ``report/budget_crlb.csv`` (:func:`report_rows`) and the report's section
(:func:`markdown`)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq

from renderlab.campaign.oat_tables import TABLES
from renderlab.stats import oat_budget as S
from renderlab.studies.retina_vs_spc.budget.plan import method_order

TABLE = "budget_crlb"
ESTIMATES = ("budget", "second", "cross", "high_a", "high_b", "clean", "footprint", "template")
BANDS = (("all", 0.0, np.inf), ("gsd<0.5", 0.0, 0.5), ("0.5<=gsd<=2", 0.5, 2.0), ("gsd>2", 2.0, np.inf))


def _noise_row(table) -> dict:
    """Medians over landmark-frames of the probe's window diagnostics (render-noise, sensor-noise sd, gradient rms) and of the CRLB ratio they
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
    """``cols`` with ``crlb_s``/``crlb_l`` replaced by ``bound`` per landmark-frame (NaN where it has none)."""
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
    methods = method_order(cols["method"])
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
