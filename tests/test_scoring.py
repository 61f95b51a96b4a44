"""Scoring statistics and the registration Cramér–Rao bound against independent oracles.

* bias/noise/median/MAD equal numpy/scipy on the same sample; the t, χ² and order-statistic
  intervals cover the true mean/σ/median at their nominal rate over 2000 seeded samples, and
  Wilson's interval covers a known failure probability;
* the CRLB of a Gaussian blob equals its closed form σ/(A·sqrt(π/2)), and a maximum-likelihood shift
  estimator (scipy least squares) on 400 noisy images reaches it;
* the DN noise variance matches the variance of the real sensor simulation;
* breakdown bins and no-result counting match direct numpy selections; ANEES of χ²(6) data falls
  inside its bounds.
"""

from __future__ import annotations

import math

import numpy as np
import pyarrow as pa
import pytest
from scipy import optimize, stats

from renderlab.campaign import scoring


def test_error_stats_match_numpy_scipy():
    x = np.random.default_rng(1).normal(0.3, 2.0, 101)
    x_nan = np.r_[x, np.nan]
    st = scoring.error_stats(x_nan)
    assert st.n == 101
    assert st.mean == pytest.approx(np.mean(x), rel=1e-12)
    assert st.std == pytest.approx(np.std(x, ddof=1), rel=1e-12)
    assert st.median == pytest.approx(np.median(x), rel=1e-12)
    assert st.mad == pytest.approx(stats.median_abs_deviation(x, scale="normal"), rel=1e-9)
    lo, hi = stats.t.interval(0.95, 100, loc=np.mean(x), scale=stats.sem(x))
    assert (st.mean_lo, st.mean_hi) == pytest.approx((lo, hi), rel=1e-9)
    assert st.rms == pytest.approx(np.sqrt(np.mean(x**2)))


def test_interval_coverage():
    rng = np.random.default_rng(7)
    n, trials, mu, sd = 20, 2000, 1.5, 0.7
    hit = np.zeros(3)
    for _ in range(trials):
        st = scoring.error_stats(rng.normal(mu, sd, n))
        hit += [st.mean_lo <= mu <= st.mean_hi, st.std_lo <= sd <= st.std_hi, st.median_lo <= mu <= st.median_hi]
    cover = hit / trials
    assert 0.935 <= cover[0] <= 0.965, cover
    assert 0.935 <= cover[1] <= 0.965, cover
    assert 0.94 <= cover[2] <= 0.99, cover  # order-statistic interval is conservative
    p, k_hits = 0.1, 0
    for _ in range(trials):
        k = int(rng.binomial(50, p))
        r, lo, hi = scoring.proportion_ci(k, 50)
        assert r == k / 50 and lo <= r <= hi
        k_hits += lo <= p <= hi
    assert 0.92 <= k_hits / trials <= 0.985
    assert scoring.proportion_ci(0, 10)[1] == 0.0


def _blob(shape, s0, l0, amp, width, bg):
    ll, ss = np.mgrid[0:shape[0], 0:shape[1]].astype(float)
    return bg + amp * np.exp(-((ss - s0) ** 2 + (ll - l0) ** 2) / width**2)


def test_crlb_closed_form_and_mle_reaches_it():
    amp, width, bg, sigma = 200.0, 3.0, 20.0, 5.0
    shape, c = (31, 33), (16.3, 15.2)
    img = _blob(shape, *c, amp, width, bg)
    cs, cl = scoring.registration_crlb(img, sigma**2)
    closed = sigma / (amp * math.sqrt(math.pi / 2))  # J = A²/σ² ∫∫ (2x/w²)² e^{-2r²/w²}: π/2 for any w
    assert cs == pytest.approx(closed, rel=0.01) and cl == pytest.approx(closed, rel=0.01)
    one_axis = scoring.registration_crlb(img, sigma**2, full=False)
    assert one_axis == pytest.approx((cs, cl), rel=1e-3)  # isotropic blob: no cross term
    rng = np.random.default_rng(3)
    est = []
    for _ in range(400):
        obs = img + rng.normal(0, sigma, shape)
        fit = optimize.least_squares(lambda p, obs=obs: (_blob(shape, p[0], p[1], amp, width, bg) - obs).ravel(),
                                     x0=[c[0] + 0.2, c[1] - 0.2])
        est.append(fit.x)
    est = np.array(est) - c
    assert np.abs(est.mean(0)).max() < 4 * closed / math.sqrt(400) * 1.5
    assert est.std(0, ddof=1) == pytest.approx([cs, cl], rel=0.12)


def test_dn_variance_matches_sensor_simulation():
    from renderlab.sensor.model import SensorOptions, expose

    opts = SensorOptions(bits=16, gain_e_per_dn=4.0, read_noise_e=12.0, full_well_e=1e6)
    rad = np.full((200, 200), 20.0)
    dn = expose(rad, opts, np.random.default_rng(0)).dn.astype(float)
    var = scoring.dn_variance(rad, opts)
    assert np.var(dn, ddof=1) == pytest.approx(var[0, 0], rel=0.03)


def _meas_table(rng, n=400):
    method = np.where(np.arange(n) % 2, "a", "b")
    es, el = rng.normal(0.2, 0.5, n), rng.normal(-0.1, 0.3, n)
    flags = (rng.random(n) < 0.1).astype(np.int64)
    es[flags == 1] = np.nan
    el[flags == 1] = np.nan
    el[5] = np.nan  # NaN without a flag also counts as no result
    phase = rng.uniform(0, 90, n)
    cols = {"campaign": ["c"] * n, "run": np.arange(n) // 4, "frame": np.zeros(n, int), "item": np.zeros(n, int),
            "method": method, "pred_s": np.zeros(n), "pred_l": np.zeros(n), "meas_s": es + 10, "meas_l": el + 10,
            "truth_s": np.full(n, 10.0), "truth_l": np.full(n, 10.0), "err_s": es, "err_l": el,
            "score": np.ones(n), "has_result": flags == 0,
            "reason": np.where(flags == 0, "ok", "low_correlation"), "outlier": np.zeros(n, bool),
            "diagnostics": [""] * n, "t_ms": np.ones(n), "phase_deg": phase}
    return pa.table(cols), method, es, el, flags, phase


def test_score_measurements_and_breakdown_match_selection():
    t, method, es, el, flags, phase = _meas_table(np.random.default_rng(5))
    assert scoring.table_kind(t) == "landmark"
    rows = {(r["method"], r["axis"]): r for r in scoring.score_measurements(t)}
    for m in "ab":
        sel = method == m
        bad = (flags == 1) | np.isnan(es) | np.isnan(el)
        r = rows[(m, "l")]
        assert r["no_result_rate"] == pytest.approx(np.mean(bad[sel]))
        good = el[sel & ~bad]
        assert r["n_result"] == len(good) and r["mean"] == pytest.approx(good.mean())
        assert r["std"] == pytest.approx(good.std(ddof=1))
    brk = scoring.breakdown(t, "phase_deg", bins=3)
    edges = np.quantile(phase, [0, 1 / 3, 2 / 3, 1])
    for r in (r for r in brk if r["axis"] == "s"):
        lo, hi = edges[r["bin"]], edges[r["bin"] + 1]
        inb = (phase >= lo) & ((phase < hi) | (r["bin"] == 2))
        sel = (method == r["method"]) & inb & ~((flags == 1) | np.isnan(es) | np.isnan(el))
        assert r["n_result"] == sel.sum() and r["mean"] == pytest.approx(es[sel].mean())
    assert scoring.breakdown(t, "no_such_column") == []


def test_filter_scoring_anees_inside_chi2_bounds():
    rng = np.random.default_rng(11)
    runs, times = 50, 20
    run = np.repeat(np.arange(runs), times)
    t_s = np.tile(np.arange(times, dtype=float), runs)
    tab = pa.table({"run": run, "t_s": t_s, "has_result": t_s > 0, "reason": np.where(t_s > 0, "ok", "prior"),
                    "err_r_m": rng.normal(0, 1, runs * times),
                    "nees": rng.chisquare(6, runs * times), "nis": rng.chisquare(2, runs * times)})
    assert scoring.table_kind(tab) == "filter"
    rows = {r["quantity"]: r for r in scoring.score_filter(tab, settle_s=5.0)}
    assert rows["err_r_m"]["n"] == runs * (times - 5)
    a = rows["anees"]
    assert a["chi2_lo"] < 6 < a["chi2_hi"] and a["chi2_lo"] < a["mean"] < a["chi2_hi"]
    assert a["fraction_inside"] >= 0.8
    bad = tab.set_column(tab.column_names.index("nees"), "nees", pa.array(2 * rng.chisquare(6, runs * times)))
    assert {r["quantity"]: r for r in scoring.score_filter(bad)}["anees"]["fraction_inside"] < 0.2


def test_filter_scoring_missing_nis_uses_each_times_own_chi2_band():
    """Where some images give no measurement (NIS = NaN), each time's ANIS is the mean over the runs that
    have one and is held against the χ² band of that count (no empty-slice averages)."""
    from scipy import stats

    rng = np.random.default_rng(12)
    runs, times = 40, 30
    run = np.repeat(np.arange(runs), times)
    t_s = np.tile(np.arange(times, dtype=float), runs)
    nis = rng.chisquare(2, runs * times)
    nis[(t_s % 3 == 0)] = np.nan                        # every third time: no image measured in any run
    nis[(t_s % 3 == 1) & (run >= 5)] = np.nan           # some times: only 5 runs measured
    tab = pa.table({"run": run, "t_s": t_s, "nees": rng.chisquare(6, runs * times), "nis": nis})
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("error")                   # a mean of an empty slice would raise here
        a = {r["quantity"]: r for r in scoring.score_filter(tab)}["anis"]
    expect = []
    for tt in range(times):
        v = nis[(t_s == tt) & np.isfinite(nis)]
        if v.size:
            lo, hi = stats.chi2.ppf([0.025, 0.975], 2 * v.size) / v.size
            expect.append(lo <= v.mean() <= hi)
    assert a["fraction_inside"] == pytest.approx(np.mean(expect)) and len(expect) == 20
    assert a["mean"] == pytest.approx(np.nanmean(nis))
