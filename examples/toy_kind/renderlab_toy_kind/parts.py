"""The ``bright_spot`` kind's parts, called by renderlab through the kind's references: runner, scorer, report
section, conformance harness; and :func:`spot_image`, the exact image of a spot both the harness and the study use."""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import numpy as np
from scipy.special import erf

from renderlab_toy_kind.kind import BRIGHT_SPOT, SpotFrame, SpotResult


def spot_image(shape, s0: float, l0: float, flux: float, sigma_px: float = 1.2, background: float = 10.0):
    """A Gaussian spot of total ``flux`` (DN) at ``(s0, l0)`` integrated over each pixel (closed form, erf), on a
    flat ``background``."""
    def axis(n, x0):
        edges = (np.arange(n + 1) - 0.5 - x0) / (np.sqrt(2) * sigma_px)
        return 0.5 * np.diff(erf(edges))

    return background + flux * np.outer(axis(shape[0], l0), axis(shape[1], s0))


def run_spots(method, frames) -> list[dict]:
    """Runner: one row per frame (the kind's columns)."""
    rows = []
    for frame in frames:
        t0 = time.perf_counter()
        try:
            res = method.locate(frame)
        except Exception as exc:  # noqa: BLE001 - a method's failure is a row, not a crash
            res = SpotResult(reason="method_error", diagnostics=f"{type(exc).__name__}: {exc}")
        BRIGHT_SPOT.check_result(res, f"frame {frame.index}: ")
        rows.append({"frame": frame.index, "method": method.name, "spot_s": res.spot_s, "spot_l": res.spot_l,
                     "sigma_px": res.sigma_px, "has_result": res.has_result, "reason": res.reason,
                     "diagnostics": res.diagnostics, "t_ms": 1e3 * (time.perf_counter() - t0)})
    return rows


def _cluster_ci(values: np.ndarray, runs: np.ndarray, confidence: float, seed: int = 0) -> tuple[float, float]:
    """Percentile bootstrap of the mean over whole runs (the frames of a run share its draw), 1000 resamples."""
    ids = np.unique(runs)
    if len(ids) < 2:
        return float("nan"), float("nan")
    rng = np.random.default_rng(seed)
    groups = [values[runs == i] for i in ids]
    means = [np.mean(np.concatenate([groups[j] for j in rng.integers(0, len(ids), len(ids))])) for _ in range(1000)]
    a = (1 - confidence) / 2
    return float(np.quantile(means, a)), float(np.quantile(means, 1 - a))


def score_spots(table, *, confidence: float = 0.95) -> list[dict]:
    """Scorer: per method and axis, rows, results, no-result rate, bias with its run-bootstrap interval, rms (px)."""
    d = table.to_pydict()
    method, ok = np.array(d["method"], object), np.array(d["has_result"], bool)
    runs = np.array(d["run"])
    out = []
    for m in sorted(set(method)):
        sel = method == m
        for axis in "sl":
            err = np.array(d.get(f"err_{axis}", [np.nan] * len(method)), float)
            keep = sel & ok & np.isfinite(err)
            lo, hi = _cluster_ci(err[keep], runs[keep], confidence)
            out.append({"method": m, "axis": axis, "n_rows": int(sel.sum()), "n_result": int((sel & ok).sum()),
                        "no_result_rate": float(1 - (sel & ok).sum() / max(sel.sum(), 1)),
                        "bias_px": float(np.mean(err[keep])) if keep.any() else float("nan"),
                        "bias_px_lo": lo, "bias_px_hi": hi,
                        "rms_px": float(np.sqrt(np.mean(err[keep] ** 2))) if keep.any() else float("nan")})
    return out


BIAS_BAND_PX = 0.05


def spot_section(name: str, table, out_dir: Path, context) -> tuple[dict, list[dict], str]:
    """Report section: the scorer's table with a PASS/FAIL on |bias| ≤ 0.05 px (its interval inside the band), the
    no-result reasons, one conclusion sentence; ``<name>_spot_summary.csv`` beside the page."""
    from renderlab.report.csvio import write_csv
    from renderlab.report.html_table import table as html_table
    from renderlab.report.style import badge

    rows = score_spots(table, confidence=context.confidence)
    write_csv(Path(out_dir) / f"{name}_spot_summary.csv", rows)
    for r in rows:
        r["badge"] = badge(bool(-BIAS_BAND_PX <= r["bias_px_lo"] and r["bias_px_hi"] <= BIAS_BAND_PX),
                           f"|bias| ≤ {BIAS_BAND_PX} px")
    cols = [("method", "method"), ("axis", "axis"), ("n_rows", "frames"), ("n_result", "results"),
            ("bias_px", "bias (px)"), ("bias_px_lo", "bias CI low (px)"), ("bias_px_hi", "bias CI high (px)"),
            ("rms_px", "rms error (px)"), ("badge", "bias in band?")]
    reasons = {}
    for m, r in zip(table.column("method").to_pylist(), table.column("reason").to_pylist()):
        reasons[(m, r)] = reasons.get((m, r), 0) + 1
    reason_rows = [{"method": m, "reason": r, "frames": n} for (m, r), n in sorted(reasons.items())]
    best = min((r for r in rows if r["n_result"]), key=lambda r: r["rms_px"], default=None)
    sentence = (f"{best['method']} locates the spot best ({best['rms_px']:.3f} px rms on {best['axis']})."
                if best else "No method located a spot.")
    blocks = [{"kind": "table", "html": html_table(rows, cols, left=("method", "axis"), raw=("badge",))},
              {"kind": "text", "html": f"95 % intervals: percentile bootstrap over runs. {sentence}"},
              {"kind": "h3", "text": "Why there is no result"},
              {"kind": "table", "html": html_table(reason_rows, [("method", "method"), ("reason", "reason"),
                                                                 ("frames", "frames")], left=("method", "reason"))}]
    return {"title": f"Bright spot: {name}", "anchor": name, "blocks": blocks}, \
        [{"table": name, **{k: v for k, v in r.items() if k != "badge"}} for r in rows], sentence


def _frames() -> dict[str, tuple[SpotFrame, tuple[float, float] | None]]:
    spot = spot_image((36, 40), 20.3, 17.6, 5000.0)
    return {"spot": (SpotFrame(spot, noise_dn=1.0, index=0, seed=1), (20.3, 17.6)),
            "blank": (SpotFrame(np.full((36, 40), 10.0), noise_dn=1.0, index=1, seed=1), None)}


def _same(a: SpotResult, b: SpotResult) -> bool:
    fa, fb = dataclasses.asdict(a), dataclasses.asdict(b)
    fa.pop("t_ms"), fb.pop("t_ms")
    return all(fa[k] == fb[k] or (isinstance(fa[k], float) and np.isnan(fa[k]) and np.isnan(fb[k])) for k in fa)


def check_spot_method(factory) -> list[str]:
    """Conformance harness, rules (a)–(e) of :mod:`renderlab_toy_kind.kind`; one line per broken rule."""
    method = factory()
    name, fails = getattr(method, "name", type(method).__name__), []
    for case, (frame, truth) in _frames().items():
        before = frame.image.copy()
        try:
            first, again = method.locate(frame), method.locate(frame)
        except Exception as exc:  # noqa: BLE001
            fails.append(f"{name} [{case}]: raised {type(exc).__name__}: {exc}")
            continue
        try:
            BRIGHT_SPOT.check_result(first, f"{name} [{case}] rule (e): ")
        except ValueError as exc:
            fails.append(str(exc))
        if not np.array_equal(frame.image, before):
            fails.append(f"{name} [{case}] rule (d): the image was modified")
        if not _same(first, again):
            fails.append(f"{name} [{case}] rule (c): a second call gave another result")
        if truth is None and (first.has_result or first.reason == "ok"):
            fails.append(f"{name} [{case}] rule (b): a result on an image without a spot")
        if truth is not None:
            tol = 3 * first.sigma_px + 0.05
            err = max(abs(first.spot_s - truth[0]), abs(first.spot_l - truth[1]))
            if not (first.has_result and err <= tol):
                fails.append(f"{name} [{case}] rule (a): error {err:.4f} px > 3σ claimed + 0.05 px = {tol:.4f}")
    return fails
