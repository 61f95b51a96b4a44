"""Statistics of a one-at-a-time error budget of landmark shifts (:mod:`renderlab.campaign.oat_budget`): per
configuration, method, subset and axis, and each source's contribution beside the registration Cramér–Rao bound.
Pure numpy on the budget's tables (any study's: the columns of :func:`columns`).

Rows: a landmark attempted in a frame with a truth pixel (``truth_visible``); "results" are those with a
measured shift. Clusters are landmark-frames (``frame``, ``item``): one landmark in one frame is seen by every
run of a configuration with the same terrain, truth image and maplet, so its errors are correlated across
runs; every interval is a 95 % percentile cluster-bootstrap interval over landmark-frames.

Statistics of the errors ``err = measured − true`` (px; axis ``s``, ``l`` or ``both``, the two axes pooled):

* ``mean``, ``robust_sigma`` (1.4826 · MAD) and ``std`` of every result (mean and std:
  :func:`renderlab.stats.bootstrap.cluster_bootstrap`; robust σ and everything below: the same multinomial
  landmark-frame counts applied as weights, vectorised over replicates, :func:`joint_weights`);
* the per-landmark decomposition on the results with |err| ≤ the gross-error threshold (1 px):
  ``bias_rms`` — rms over landmark-frames of the landmark-frame's mean error over runs (what a filter sees
  as a per-landmark bias), and ``noise_sd`` — the pooled within-landmark-frame standard deviation over runs
  (what it sees as noise; zero by construction where all runs are identical);
* ``crlb`` — median over landmark-frames of the registration CRLB ``crlb_s``/``crlb_l``
  (:func:`renderlab.campaign.scoring.registration_crlb`: √ of the diagonal of J⁻¹, J = Σ ∇I ∇Iᵀ / σ² the
  Fisher information of an (s, l) shift of the noise-free truth image I in Gaussian pixel noise σ²) and
  ``noise_over_crlb`` — √(mean over landmark-frames and axes of noise variance / CRLB²), the rms ratio
  (unbiased in the variance, unlike a median of few-run standard deviations), interval by resampling them.

A source's contribution to a statistic v is ``sign(d)·√|d|`` with d = v²(source alone) − v²(all off), and the
quadrature sum of the budget is ``√(v²(all off) + Σ d)``, compared with v(all on). Their intervals come from
one *joint* cluster bootstrap: each replicate draws one multinomial weight per landmark-frame and applies it
to every configuration, so the paired structure (same landmarks, same run seeds) is kept.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from renderlab.stats.bootstrap import MAD_TO_SIGMA, cluster_bootstrap

CONFIDENCE = 0.95
AXES = ("s", "l", "both")
STATS = ("robust_sigma", "std", "bias_rms", "noise_sd")


@dataclass(frozen=True)
class Sample:
    """The results of one (configuration, method, subset, axis): errors, landmark-frame index per row (into
    the folder-wide universe of landmark-frames: the bootstrap unit), ``group`` = 2 · landmark-frame + axis
    (0: s, 1: l; the unit of a per-landmark mean and spread), CRLB per row, attempted rows and the runs."""

    err: np.ndarray
    cluster: np.ndarray
    group: np.ndarray
    crlb: np.ndarray
    attempted: int
    runs: int


def columns(table) -> dict:
    """The budget measurement table as numpy columns (``config``, ``method``, ``reason``; ``run``, ``frame``,
    ``item``; ``has_result``, ``truth_visible``; ``err_s``, ``err_l``, ``crlb_s``, ``crlb_l`` and every other
    floating-point column as float), with ``cluster`` (int per landmark-frame) and ``n_clusters``."""
    out = {}
    for name in ("config", "method", "reason"):
        out[name] = np.asarray(table.column(name).to_pylist(), dtype=object)
    for name in ("run", "frame", "item"):
        out[name] = np.asarray(table.column(name).to_numpy(zero_copy_only=False), np.int64)
    floats = [f.name for f in table.schema if str(f.type) in ("float", "double", "halffloat")]
    for name in dict.fromkeys(("err_s", "err_l", "crlb_s", "crlb_l", *floats)):
        out[name] = np.asarray(table.column(name).to_numpy(zero_copy_only=False), float)
    for name in ("has_result", "truth_visible"):
        out[name] = np.asarray(table.column(name).to_numpy(zero_copy_only=False), bool)
    keys = out["frame"] * 1_000_000 + out["item"]
    uniq, out["cluster"] = np.unique(keys, return_inverse=True)
    out["n_clusters"] = int(uniq.size)
    return out


def sample(cols: dict, config: str, method: str, subset: np.ndarray, axis: str, runs: int) -> Sample:
    """The :class:`Sample` of one configuration/method/subset/axis."""
    rows = (cols["config"] == config) & (cols["method"] == method) & subset & cols["truth_visible"]
    parts = ("s", "l") if axis == "both" else (axis,)
    err = np.concatenate([cols[f"err_{a}"][rows] for a in parts])
    clu = np.concatenate([cols["cluster"][rows] for _ in parts])
    grp = np.concatenate([2 * cols["cluster"][rows] + "sl".index(a) for a in parts])
    crlb = np.concatenate([cols[f"crlb_{a}"][rows] for a in parts])
    ok = np.isfinite(err)
    return Sample(err[ok], clu[ok], grp[ok], crlb[ok], int(rows.sum()) * len(parts), int(runs))


def _robust(x: np.ndarray, w: np.ndarray) -> np.ndarray:
    """1.4826 × the weighted MAD per row of ``w`` (R, n): the weighted median m (smallest value with half the
    weight at or below it), then the smallest t with half the weight in [m − t, m + t] (bisection on t, one
    sort of ``x`` shared by every replicate)."""
    o = np.argsort(x, kind="stable")
    xs = x[o]
    cw = np.cumsum(w[:, o], axis=-1)
    half = 0.5 * cw[:, -1]
    rows = np.arange(w.shape[0])

    def below(v, side):  # weight of x <= v (side "right") or x < v ("left"), per replicate
        i = np.searchsorted(xs, v, side=side)
        return np.where(i > 0, cw[rows, np.maximum(i - 1, 0)], 0.0)

    def smallest_t(inside):  # smallest t >= 0 with inside(t) true (inside is monotone in t)
        lo, hi = np.zeros_like(med), np.full_like(med, float(xs[-1] - xs[0]) + 1.0)
        for _ in range(44):  # 2^-44 of the range: exact to the digits written
            mid = 0.5 * (lo + hi)
            ok = inside(mid)
            hi, lo = np.where(ok, mid, hi), np.where(ok, lo, mid)
        return hi

    last = xs.size - 1  # lower and upper weighted medians, averaged (numpy's median for an even count)
    med = 0.5 * (xs[np.minimum((cw < half[:, None]).sum(-1), last)] + xs[np.minimum((cw <= half[:, None]).sum(-1), last)])
    mad_lo = smallest_t(lambda t: below(med + t, "right") - below(med - t, "left") >= half)
    mad_hi = smallest_t(lambda t: below(med + t, "right") - below(med - t, "left") > half)
    return MAD_TO_SIGMA * 0.5 * (mad_lo + mad_hi)


def weighted_stat(name: str, s: Sample, wc: np.ndarray, gross_px: float):
    """Statistic ``name`` of ``s`` with weight ``wc[k]`` on every row of landmark-frame k (all ones: the data).

    ``wc`` is (K,) → a float, or (R, K) replicates → (R,) (a replicate's integer weights are the landmark-frames
    drawn with replacement, so every statistic equals the one of the repeated rows)."""
    one = np.ndim(wc) == 1
    wc = np.atleast_2d(np.asarray(wc, float))
    val = _stat(name, s, wc, gross_px)
    return float(val[0]) if one else val


def _stat(name: str, s: Sample, wc: np.ndarray, gross_px: float) -> np.ndarray:
    nan = np.full(wc.shape[0], np.nan)
    x, c = s.err, s.cluster
    if name in ("robust_sigma", "std", "mean"):
        if x.size == 0:
            return nan
        w = wc[:, c]
        n = w.sum(-1)
        with np.errstate(invalid="ignore", divide="ignore"):
            m = (w * x).sum(-1) / n
            if name == "mean":
                return np.where(n >= 1, m, np.nan)
            if name == "std":
                return np.where(n >= 2, np.sqrt((w * (x - m[:, None]) ** 2).sum(-1) / (n - 1)), np.nan)
        return np.where(n >= 2, _robust(x, w), np.nan)
    core = np.abs(x) <= gross_px
    x, c = x[core], s.group[core]  # per landmark-frame and axis; weights per landmark-frame
    wc = np.repeat(wc, 2, axis=1)
    K = wc.shape[1]
    nc = np.bincount(c, minlength=K).astype(float)
    sx = np.bincount(c, x, minlength=K)
    sxx = np.bincount(c, x * x, minlength=K)
    with np.errstate(invalid="ignore", divide="ignore"):
        if name == "bias_rms":
            has = nc > 0
            m2 = np.where(has, (sx / np.where(has, nc, 1)) ** 2, 0.0)
            return np.sqrt((wc * m2).sum(-1) / (wc * has).sum(-1))
        if s.runs < 2:
            return np.zeros(wc.shape[0])  # every run identical: no noise by construction
        two = nc >= 2
        ss = np.where(two, sxx - sx ** 2 / np.where(two, nc, 1), 0.0)
        dof = (wc * np.where(two, nc - 1, 0)).sum(-1)
        return np.sqrt(np.clip((wc * ss).sum(-1), 0, None) / dof)


def noise_over_crlb(s: Sample, gross_px: float) -> np.ndarray:
    """Per landmark-frame and axis (with ≥ 2 core results and a finite CRLB) noise variance / CRLB²."""
    core = np.abs(s.err) <= gross_px
    g, x = s.group[core], s.err[core]
    if g.size == 0:
        return np.array([])
    K = int(g.max()) + 1
    n = np.bincount(g, minlength=K).astype(float)
    sx, sxx = np.bincount(g, x, minlength=K), np.bincount(g, x * x, minlength=K)
    crlb = np.full(K, np.nan)
    crlb[g] = s.crlb[core]  # one CRLB per landmark-frame and axis (the truth image's)
    ok = (n >= 2) & np.isfinite(crlb) & (crlb > 0)
    var = (sxx[ok] - sx[ok] ** 2 / n[ok]) / (n[ok] - 1)
    return np.clip(var, 0, None) / crlb[ok] ** 2


def _ci(reps: np.ndarray) -> tuple[float, float]:
    r = reps[np.isfinite(reps)]
    if r.size < 10:
        return float("nan"), float("nan")
    a = 100 * (1 - CONFIDENCE) / 2
    return float(np.percentile(r, a)), float(np.percentile(r, 100 - a))


def summary_row(s: Sample, weights: np.ndarray, gross_px: float, n_boot: int, seed: int) -> dict:
    """Every statistic of one sample with its interval (``weights``: the joint replicates, (n_boot, K))."""
    row = {"attempted": s.attempted, "results": int(s.err.size),
           "no_result_rate": 1 - s.err.size / s.attempted if s.attempted else float("nan"),
           "gross_rate": float(np.mean(np.abs(s.err) > gross_px)) if s.err.size else float("nan"),
           "landmark_frames": int(np.unique(s.cluster).size)}
    for st in ("mean", "std"):
        iv = cluster_bootstrap(s.err, s.cluster, st, confidence=CONFIDENCE, n_boot=n_boot, rng=seed,
                               cluster_name="landmark-frames")
        row.update({st: iv.estimate, f"{st}_lo": iv.lo, f"{st}_hi": iv.hi})
    ones = np.ones(weights.shape[1])
    for st in ("robust_sigma", "bias_rms", "noise_sd"):
        row[st] = weighted_stat(st, s, ones, gross_px)
        row[f"{st}_lo"], row[f"{st}_hi"] = _ci(weighted_stat(st, s, weights, gross_px))
    row["crlb"] = float(np.nanmedian(s.crlb)) if np.isfinite(s.crlb).any() else float("nan")
    r = noise_over_crlb(s, gross_px) if s.runs >= 2 else np.array([])
    row["noise_over_crlb"] = float(np.sqrt(np.mean(r))) if r.size else float("nan")
    if r.size >= 10:
        rng = np.random.default_rng(seed)
        reps = np.sqrt(np.mean(r[rng.integers(0, r.size, (n_boot, r.size))], axis=1))
        row["noise_over_crlb_lo"], row["noise_over_crlb_hi"] = _ci(reps)
    else:
        row["noise_over_crlb_lo"] = row["noise_over_crlb_hi"] = float("nan")
    return row


def joint_weights(n_clusters: int, n_boot: int, seed: int) -> np.ndarray:
    """(n_boot, K) multinomial landmark-frame counts, one draw per replicate shared by every configuration."""
    rng = np.random.default_rng(seed)
    return rng.multinomial(n_clusters, np.full(n_clusters, 1.0 / n_clusters), size=n_boot).astype(float)


def _terms(st: str, samples: dict, have: list, w: np.ndarray, gross_px: float) -> dict:
    """The budget terms of statistic ``st`` for weights ``w`` ((K,) or (R, K))."""
    v = {k: np.asarray(weighted_stat(st, samples[k], w, gross_px), float) for k in ("all_off", "all_on", *have)}
    d = {k: v[k] ** 2 - v["all_off"] ** 2 for k in have}
    q = v["all_off"] ** 2 + sum(d.values())
    with np.errstate(invalid="ignore", divide="ignore"):
        t = {"all_off": v["all_off"], **{k: np.sign(x) * np.sqrt(np.abs(x)) for k, x in d.items()},
             "quadrature_sum": np.where(q >= 0, np.sqrt(np.abs(q)), np.nan), "all_on": v["all_on"]}
        t["sum_over_all_on"] = np.where(v["all_on"] > 0, t["quadrature_sum"] / v["all_on"], np.nan)
    return t


def budget_rows(samples: dict, sources: list[str], weights: np.ndarray, gross_px: float) -> list[dict]:
    """Per statistic: each source's contribution, the quadrature sum and its ratio to all-on, with intervals.

    ``samples`` maps configuration → :class:`Sample` (``all_off``, ``all_on`` and each source) of one method,
    subset and axis. Rows: ``{"statistic", "term", "value", "lo", "hi"}`` with term ``all_off``, a source,
    ``quadrature_sum``, ``all_on`` and ``sum_over_all_on``.
    """
    ones = np.ones(weights.shape[1])
    out = []
    have = [s for s in sources if s in samples]
    for st in STATS:
        est, reps = _terms(st, samples, have, ones, gross_px), _terms(st, samples, have, weights, gross_px)
        for k, val in est.items():
            lo, hi = _ci(reps[k])
            out.append({"statistic": st, "term": k, "value": float(val), "lo": lo, "hi": hi})
    return out
