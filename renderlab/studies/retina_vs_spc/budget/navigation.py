"""The error budget's contribution to navigation error: each configuration's landmark errors as an error model
(:class:`ErrorModel`, eq. N1 of ``docs/retina_vs_spc.md``: mean μ, per-landmark bias spread σ_b and noise σ_n per
image axis at knots of depth) that the descent study flies through its filter
(:mod:`renderlab.studies.descent_navigation.error_flights`), under three :data:`MAPPINGS` of the budget's three
frames onto the descent's altitudes (``altitude``: log-depth interpolation; ``ground``: constant in metres;
``pixel``: constant in pixels). Configuration ``no_landmark_error`` (:data:`NONE_CONFIG`) injects nothing: the floor.

``renderlab navigation-budget results/error_budget --runs 200`` (:mod:`renderlab.commands.navigation_budget`) writes
``tables/budget_navigation.parquet`` (:data:`TABLE`: one row per mapping, configuration, method and run: touchdown-proxy
error east / north / up, the filter's 1σ, NEES, track loss, the injected model) and
``tables/budget_navigation_rendered.parquet`` (:data:`RENDERED`), then the report (:mod:`.navigation_report`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from renderlab.errors import UserError
from renderlab.stats import oat_budget as S

MAPPINGS = ("altitude", "ground", "pixel")
NONE_CONFIG, NONE_METHOD = "no_landmark_error", "none"
TABLE, RENDERED = "budget_navigation", "budget_navigation_rendered"


@dataclass(frozen=True)
class NavBudgetOptions:
    """Options of the navigation budget (module docstring)."""
    runs: int = 200
    seed: int = 2027
    mappings: tuple = MAPPINGS
    gross_px: float = 1.0


@dataclass(frozen=True)
class ErrorModel:
    """One configuration × method × mapping: eq. N1's μ, σ_b, σ_n per axis (s, l) at knots of depth R; ``unit`` ``"px"``
    (at each knot of ``knots_m``) or ``"m"`` (on the ground, one knot; σ_px = σ_m f_x / R)."""

    config: str
    method: str
    mapping: str
    unit: str
    knots_m: np.ndarray      # (K,) median depth of each knot's rows
    mu: np.ndarray           # (K, 2)
    sd_bias: np.ndarray      # (K, 2)
    sd_noise: np.ndarray     # (K, 2)
    bias_rms: np.ndarray     # (K, 2) the budget's per-landmark bias rms
    landmark_frames: int

    def at(self, depth_m: np.ndarray, fx: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(μ, σ_b, σ_n), each (n, 2) px, at depths ``depth_m`` (n,)."""
        d = np.asarray(depth_m, float)
        if self.unit == "m":
            f = (fx / d)[:, None]
            return self.mu[0] * f, self.sd_bias[0] * f, self.sd_noise[0] * f
        if len(self.knots_m) == 1:
            return tuple(np.broadcast_to(a[0], (d.size, 2)).copy() for a in (self.mu, self.sd_bias, self.sd_noise))
        o = np.argsort(self.knots_m)
        x = np.log(d)

        def interp(a):
            return np.stack([np.interp(x, np.log(self.knots_m[o]), a[o, j]) for j in range(2)], axis=1)

        return interp(self.mu), interp(self.sd_bias), interp(self.sd_noise)


def _axis_stats(e: np.ndarray, cluster: np.ndarray, runs: int) -> tuple[float, float, float]:
    """(mean, per-landmark bias rms, pooled within-landmark noise sd) of errors e grouped by cluster."""
    u, inv = np.unique(cluster, return_inverse=True)
    n = np.bincount(inv).astype(float)
    sx, sxx = np.bincount(inv, e), np.bincount(inv, e * e)
    mean_k = sx / n
    two = n >= 2
    noise = 0.0
    if runs >= 2 and two.any():
        noise = math.sqrt(max(float(np.sum(sxx[two] - sx[two] ** 2 / n[two])), 0.0) / float(np.sum(n[two] - 1)))
    return float(np.mean(e)), float(np.sqrt(np.mean(mean_k ** 2))), noise


def error_models(meas, configs, fx: float, gsd_range: tuple, mapping: str, gross_px: float = 1.0) -> list:
    """The :class:`ErrorModel` of every configuration × method of a budget's tables under ``mapping``."""
    if mapping not in MAPPINGS:
        raise UserError(f"navigation budget: mapping must be one of {', '.join(MAPPINGS)}, got {mapping!r}")
    cols = S.columns(meas)
    depth = np.asarray(meas.column("range_m").to_numpy(zero_copy_only=False), float)
    runs = dict(zip(configs.column("config").to_pylist(), configs.column("runs").to_pylist()))
    g = cols["gsd_ratio"]
    base = cols["truth_visible"] & (g >= gsd_range[0]) & (g <= gsd_range[1])
    frames = np.unique(cols["frame"][base])
    out = []
    for c in runs:
        for m in sorted(set(cols["method"][cols["config"] == c])):
            sel = base & (cols["config"] == c) & (cols["method"] == m)
            groups = [sel & (cols["frame"] == f) for f in frames] if mapping == "altitude" else [sel]
            scale = depth / fx if mapping == "ground" else np.ones_like(depth)
            knots, stats = [], []
            for rows in groups:
                per_axis = []
                for a in "sl":
                    ok = rows & np.isfinite(cols[f"err_{a}"]) & (np.abs(cols[f"err_{a}"]) <= gross_px)
                    if ok.sum() < 2:
                        raise UserError(f"navigation budget: configuration {c}, method {m} has fewer than 2 "
                                        f"results in the GSD-ratio range {gsd_range}")
                    per_axis.append(_axis_stats(cols[f"err_{a}"][ok] * scale[ok], cols["cluster"][ok], runs[c]))
                knots.append(float(np.median(depth[rows])))
                stats.append(per_axis)
            st = np.array(stats)                                  # (K, 2 axes, 3)
            mu, brms, noise = st[..., 0], st[..., 1], st[..., 2]
            out.append(ErrorModel(c, m, mapping, "m" if mapping == "ground" else "px", np.array(knots), mu,
                                  np.sqrt(np.clip(brms ** 2 - mu ** 2, 0, None)), noise, brms,
                                  int(np.unique(cols["cluster"][sel]).size)))
    return out


def term_order(rows: list[dict]) -> list[str]:
    """The terms of ``rows`` in the budget's order: floor, all off, sources, the all-off terms, sum, all on."""
    late = ("peak_step", "shadow_approximation", "quadrature_sum", "all_on", "sum_over_all_on")
    terms = list(dict.fromkeys(r["term"] for r in rows))
    return [t for t in terms if t not in late] + [t for t in late if t in terms]
