"""renderlab.stats.bootstrap: coverage of the cluster bootstrap on clustered data, and independent oracles.

Acceptance criterion: on a random-effect model (value = u_cluster + e_row, u, e ~ N(0, 1), true mean 0),
nominal 95 % cluster-bootstrap intervals of the mean cover the truth 93–97 % of the time, while i.i.d.
Student-t intervals on the same data under-cover badly (rows within a cluster are correlated, ICC = 0.5).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy import stats

from renderlab.stats.bootstrap import (
    Interval,
    cluster_bootstrap,
    cluster_bootstrap_rate,
    iid_interval,
    paired_difference,
)

# 200 clusters: with 60, the percentile interval's (G-1)/G shrinkage and normal-vs-t quantiles put the expected
# coverage at ~0.943, too close to the band's edge for 2000 replications (Monte Carlo SE 0.005).
N_CLUSTERS, ROWS_PER_CLUSTER, N_REP, N_BOOT = 200, 30, 2000, 1000


def test_cluster_bootstrap_covers_nominal_and_iid_undercovers():
    rng = np.random.default_rng(0)
    boot_rng = np.random.default_rng(1)
    cl = np.repeat(np.arange(N_CLUSTERS), ROWS_PER_CLUSTER)
    hit_cluster = np.zeros(N_REP, bool)
    hit_iid = np.zeros(N_REP, bool)
    for r in range(N_REP):
        v = rng.standard_normal(N_CLUSTERS)[cl] + rng.standard_normal(cl.size)
        hit_cluster[r] = cluster_bootstrap(v, cl, "mean", n_boot=N_BOOT, rng=boot_rng).contains(0.0)
        hit_iid[r] = iid_interval(v, "mean").contains(0.0)
    cov_c, cov_i = hit_cluster.mean(), hit_iid.mean()
    se = math.sqrt(0.95 * 0.05 / N_REP)
    print(f"\ncoverage of nominal 95 % intervals over {N_REP} replications ({N_CLUSTERS} clusters x "
          f"{ROWS_PER_CLUSTER} rows, ICC 0.5): cluster bootstrap {cov_c:.4f} (MC SE {se:.4f}), i.i.d. t {cov_i:.4f}")
    assert 0.93 <= cov_c <= 0.97, cov_c
    assert cov_i < 0.80, cov_i


# ---- independent oracles on i.i.d. data (every row its own cluster) -------------------------------------

@pytest.fixture(scope="module")
def iid_data():
    x = np.random.default_rng(42).normal(2.0, 3.0, size=2000)
    return x, np.arange(x.size)


def _close(iv: Interval, lo: float, hi: float, tol: float = 0.10):
    w = hi - lo
    assert abs(iv.lo - lo) < tol * w and abs(iv.hi - hi) < tol * w, (iv, lo, hi)
    assert abs(iv.hi - iv.lo - w) < tol * w, (iv, lo, hi)


def test_iid_mean_matches_student_t(iid_data):
    x, c = iid_data
    lo, hi = stats.t.interval(0.95, x.size - 1, loc=x.mean(), scale=stats.sem(x))
    iv = cluster_bootstrap(x, c, "mean", n_boot=4000, rng=3)
    assert iv.estimate == pytest.approx(x.mean())
    _close(iv, lo, hi)
    t = iid_interval(x, "mean")
    assert (t.lo, t.hi) == pytest.approx((lo, hi), rel=1e-12)
    assert t.method == "i.i.d. Student-t" and t.n == t.n_clusters == x.size


def test_iid_std_matches_chi_square(iid_data):
    x, c = iid_data
    n, s = x.size, x.std(ddof=1)
    lo = s * math.sqrt((n - 1) / stats.chi2.ppf(0.975, n - 1))
    hi = s * math.sqrt((n - 1) / stats.chi2.ppf(0.025, n - 1))
    iv = cluster_bootstrap(x, c, "std", n_boot=4000, rng=3)
    assert iv.estimate == pytest.approx(s)
    _close(iv, lo, hi)
    assert (iid_interval(x, "std").lo, iid_interval(x, "std").hi) == pytest.approx((lo, hi), rel=1e-12)


@pytest.mark.parametrize("stat, fn", [
    ("mean", np.mean),
    ("std", lambda a, axis=-1: np.std(a, ddof=1, axis=axis)),
    ("rms", lambda a, axis=-1: np.sqrt(np.mean(a * a, axis=axis))),
    ("median", np.median),
])
def test_matches_scipy_percentile_bootstrap(iid_data, stat, fn):
    x, c = iid_data
    ref = stats.bootstrap((x,), fn, method="percentile", n_resamples=2000, confidence_level=0.95,
                          random_state=np.random.default_rng(105)).confidence_interval  # its own draws
    iv = cluster_bootstrap(x, c, stat, n_boot=2000, rng=5)
    _close(iv, ref.low, ref.high)


def test_clustered_mean_equals_bootstrap_of_cluster_means():
    """Equal-size clusters: resampling clusters for the mean = i.i.d. bootstrap of the cluster means."""
    rng = np.random.default_rng(7)
    g, m = 150, 12
    cl = np.repeat(np.arange(g), m)
    v = rng.standard_normal(g)[cl] + rng.standard_normal(g * m)
    means = v.reshape(g, m).mean(axis=1)
    ref = stats.bootstrap((means,), np.mean, method="percentile", n_resamples=4000,
                          random_state=np.random.default_rng(108)).confidence_interval
    iv = cluster_bootstrap(v, cl, "mean", n_boot=4000, rng=8)
    _close(iv, ref.low, ref.high)
    assert iv.hi - iv.lo > 2.5 * (iid_interval(v).hi - iid_interval(v).lo)  # design effect 1 + 11·0.5 = 6.5


@pytest.mark.parametrize("stat, fn", [
    ("mean", np.mean),
    ("std", lambda a: np.std(a, ddof=1)),
    ("rms", lambda a: np.sqrt(np.mean(a * a))),
])
def test_closed_form_matches_resampled_indices(stat, fn):
    """The fast per-cluster-sum path gives the same interval as resampling rows through a callable."""
    rng = np.random.default_rng(11)
    sizes = rng.integers(1, 9, size=80)  # unequal cluster sizes
    cl = np.repeat(np.arange(80), sizes)
    v = 1.0 + rng.standard_normal(80)[cl] * 0.7 + rng.standard_normal(cl.size)
    fast = cluster_bootstrap(v, cl, stat, n_boot=500, rng=2)
    slow = cluster_bootstrap(v, cl, fn, n_boot=500, rng=2)  # same seed → same cluster draws
    assert (fast.estimate, fast.lo, fast.hi) == pytest.approx((slow.estimate, slow.lo, slow.hi), rel=1e-9)


def test_robust_sigma_of_normal_data(iid_data):
    x, c = iid_data
    iv = cluster_bootstrap(x, c, "robust_sigma", n_boot=300, rng=0)
    assert iv.lo < 3.0 < iv.hi and iv.estimate == pytest.approx(3.0, rel=0.05)


# ---- determinism, NaNs, degenerate inputs ---------------------------------------------------------------

def _clustered(seed=0, g=40, m=5):
    rng = np.random.default_rng(seed)
    cl = np.repeat(np.arange(g), m)
    return rng.standard_normal(g)[cl] + rng.standard_normal(g * m), cl


def test_deterministic():
    v, cl = _clustered()
    for stat in ("mean", "median"):
        a = cluster_bootstrap(v, cl, stat, n_boot=300, rng=9)
        assert a == cluster_bootstrap(v, cl, stat, n_boot=300, rng=9)
        assert a == cluster_bootstrap(v, cl, stat, n_boot=300, rng=np.random.default_rng(9))
        assert cluster_bootstrap(v, cl, stat, n_boot=300) == cluster_bootstrap(v, cl, stat, n_boot=300)  # seed 0
        assert a != cluster_bootstrap(v, cl, stat, n_boot=300, rng=10)
    with pytest.raises(dataclasses.FrozenInstanceError):
        a.lo = 0.0


def test_nans_dropped_with_their_clusters():
    v, cl = _clustered()
    w = v.copy()
    w[[3, 17, 18, 100]] = np.nan
    ok = ~np.isnan(w)
    for stat in ("mean", "std", "median"):
        got = cluster_bootstrap(w, cl, stat, n_boot=300, rng=4)
        assert got == cluster_bootstrap(v[ok], cl[ok], stat, n_boot=300, rng=4)
        assert got.n == ok.sum() and got.n_clusters == 40 and np.isfinite([got.estimate, got.lo, got.hi]).all()
    w[cl == 0] = np.nan  # a whole cluster gone
    assert cluster_bootstrap(w, cl, n_boot=50).n_clusters == 39


def test_fewer_than_two_clusters_gives_nan():
    one = cluster_bootstrap([1.0, 2.0, 3.0], ["a", "a", "a"])
    assert one.estimate == 2.0 and math.isnan(one.lo) and math.isnan(one.hi) and one.n_clusters == 1
    none = cluster_bootstrap([np.nan, np.nan], [1, 2])
    assert math.isnan(none.estimate) and math.isnan(none.lo) and none.n == 0
    empty = cluster_bootstrap([], [], "median")
    assert math.isnan(empty.estimate) and empty.n == empty.n_clusters == 0
    with pytest.raises(ValueError):
        cluster_bootstrap([1.0, 2.0], [1])
    with pytest.raises(ValueError):
        cluster_bootstrap([1.0, 2.0], [1, 2], "mode")


def test_method_names_the_clustering():
    v, cl = _clustered()
    iv = cluster_bootstrap(v, cl, n_boot=123, cluster_name="landmark-frames")
    assert iv.method == "cluster bootstrap (percentile, 123 resamples, clusters = landmark-frames)"
    assert iv.n == v.size and iv.n_clusters == 40


# ---- rates and paired differences -----------------------------------------------------------------------

def test_rate_whole_clusters_flagged():
    """30 of 100 clusters entirely flagged: the rate's interval is that of a binomial over 100 clusters."""
    cl = np.repeat(np.arange(100), 10)
    flags = np.isin(cl, np.random.default_rng(0).choice(100, 30, replace=False))
    iv = cluster_bootstrap_rate(flags, cl, n_boot=4000, rng=1)
    assert iv.estimate == pytest.approx(0.3)
    lo, hi = stats.binom.ppf([0.025, 0.975], 100, 0.3) / 100
    assert iv.lo == pytest.approx(lo, abs=0.02) and iv.hi == pytest.approx(hi, abs=0.02)
    # i.i.d. over rows would claim 10x the information
    p = 0.3
    assert iv.hi - iv.lo > 2.5 * 2 * 1.96 * math.sqrt(p * (1 - p) / flags.size)


def test_rate_edge_cases():
    cl = np.repeat(np.arange(20), 5)
    assert cluster_bootstrap_rate(np.zeros(100, bool), cl) == Interval(
        0.0, 0.0, 0.0, 100, 20, "cluster bootstrap (percentile, 2000 resamples, clusters = clusters)")
    iv = cluster_bootstrap_rate(np.ones(100, bool), cl)
    assert (iv.estimate, iv.lo, iv.hi) == (1.0, 1.0, 1.0)
    f = np.where(np.arange(100) % 2 == 0, 1.0, np.nan)  # NaN = not applicable
    assert cluster_bootstrap_rate(f, cl).n == 50


def test_paired_constant_shift_is_exact():
    b = np.random.default_rng(0).standard_normal(200)
    cl = np.repeat(np.arange(40), 5)
    iv = paired_difference(b + 0.5, b, cl)
    assert (iv.estimate, iv.lo, iv.hi) == pytest.approx((0.5, 0.5, 0.5), abs=1e-12)


def test_paired_cancels_shared_cluster_effect():
    rng = np.random.default_rng(3)
    g, m = 100, 8
    cl = np.repeat(np.arange(g), m)
    u = 3.0 * rng.standard_normal(g)[cl]  # shared by both methods: cancels in the paired difference
    a = u + 0.3 + 0.5 * rng.standard_normal(g * m)
    b = u + 0.5 * rng.standard_normal(g * m)
    a[::7] = np.nan
    b[::11] = np.inf
    ok = np.isfinite(a) & np.isfinite(b)
    iv = paired_difference(a, b, cl, n_boot=2000, rng=0)
    assert iv.n == ok.sum() and iv.lo < 0.3 < iv.hi
    assert iv.hi - iv.lo < 0.2  # ≈ 4 × 0.5·√2 / √(n): far narrower than the cluster spread
    unpaired = cluster_bootstrap(a, cl, n_boot=2000, rng=0)
    assert unpaired.hi - unpaired.lo > 5 * (iv.hi - iv.lo)
    med = paired_difference(a, b, cl, "median", n_boot=300, rng=0)
    assert med.lo < 0.3 < med.hi
