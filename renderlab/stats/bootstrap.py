"""Cluster bootstrap: confidence intervals for data whose rows are correlated within clusters.

Rows that share a cluster (e.g. the same landmark in the same frame, seen over many runs) are not
independent, so i.i.d. intervals are too narrow. The cluster bootstrap resamples whole clusters with
replacement (multinomial cluster counts) and recomputes the statistic on each resample; the interval
is the percentile interval of those replicates.

"mean", "std" and "rms" use a closed form from per-cluster sums (count, Σx, Σx²): one matrix product
per statistic, no resampled arrays. Other statistics ("median", "robust_sigma", a callable) resample
row indices. NaNs in ``values`` are dropped, with their cluster entries, before anything else.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Union

import numpy as np
from scipy import stats as _st

MAD_TO_SIGMA = 1.482602218505602  # 1 / Φ⁻¹(3/4): MAD of a normal variable → its σ

Stat = Union[str, Callable[[np.ndarray], float]]
_CLOSED = ("mean", "std", "rms")


@dataclass(frozen=True)
class Interval:
    """A point estimate with a confidence interval.

    Attributes
    ----------
    estimate : float
        The statistic on the data as given (NaN when there are no rows).
    lo, hi : float
        Lower and upper confidence limits (NaN when they cannot be estimated).
    n : int
        Rows used (after dropping NaNs).
    n_clusters : int
        Distinct clusters among those rows (``n`` for i.i.d. intervals).
    method : str
        How the interval was made, in words, for reports.
    """

    estimate: float
    lo: float
    hi: float
    n: int
    n_clusters: int
    method: str

    def contains(self, x: float) -> bool:
        """Whether ``lo <= x <= hi``."""
        return bool(self.lo <= x <= self.hi)


def _robust_sigma(x: np.ndarray) -> float:
    return float(MAD_TO_SIGMA * np.median(np.abs(x - np.median(x))))


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x * x)))


_NAMED: dict[str, Callable[[np.ndarray], float]] = {
    "mean": lambda x: float(np.mean(x)),
    "std": lambda x: float(np.std(x, ddof=1)) if len(x) > 1 else np.nan,
    "median": lambda x: float(np.median(x)),
    "robust_sigma": _robust_sigma,
    "rms": _rms,
}


def _stat_fn(stat: Stat) -> Callable[[np.ndarray], float]:
    if callable(stat):
        return stat
    if stat not in _NAMED:
        raise ValueError(f"unknown stat {stat!r}; expected one of {sorted(_NAMED)} or a callable")
    return _NAMED[stat]


def _rng(rng) -> np.random.Generator:
    if rng is None:
        return np.random.default_rng(0)
    if isinstance(rng, np.random.Generator):
        return rng
    return np.random.default_rng(rng)


def cluster_bootstrap(values, clusters, stat: Stat = "mean", *, confidence: float = 0.95, n_boot: int = 2000,
                      rng=None, cluster_name: str = "clusters") -> Interval:
    """Percentile cluster-bootstrap interval of ``stat(values)``.

    Parameters
    ----------
    values : array_like, shape (n,)
        One value per row; NaN rows are dropped (with their ``clusters`` entries).
    clusters : array_like, shape (n,)
        Cluster label per row (any sortable labels: ints, strings).
    stat : {"mean", "std", "median", "robust_sigma", "rms"} or callable
        ``"std"`` has ``ddof=1``; ``"robust_sigma"`` is MAD × 1.4826; a callable maps a 1-D array to a float.
    confidence : float
        Two-sided confidence level.
    n_boot : int
        Bootstrap resamples.
    rng : numpy.random.Generator or int, optional
        Generator (advanced in place) or seed; default seed 0, so results are deterministic.
    cluster_name : str
        Name of the clustering, for ``Interval.method``.

    Returns
    -------
    Interval
        ``lo``/``hi`` are NaN with fewer than 2 clusters; ``estimate`` is NaN with no rows.
    """
    x = np.asarray(values, dtype=float).ravel()
    c = np.asarray(clusters).ravel()
    if x.shape != c.shape:
        raise ValueError(f"values and clusters differ in length: {x.shape[0]} vs {c.shape[0]}")
    keep = ~np.isnan(x)
    x, c = x[keep], c[keep]
    fn = _stat_fn(stat)
    method = f"cluster bootstrap (percentile, {n_boot} resamples, clusters = {cluster_name})"
    if len(x) == 0:
        return Interval(np.nan, np.nan, np.nan, 0, 0, method)
    uniq, inv = np.unique(c, return_inverse=True)
    inv = inv.ravel()
    k = len(uniq)
    est = float(fn(x))
    if k < 2:
        return Interval(est, np.nan, np.nan, len(x), k, method)
    draws = _cluster_draws(_rng(rng), k, n_boot)
    if not callable(stat) and stat in _CLOSED:
        n = np.bincount(inv, minlength=k).astype(float)
        s1 = np.bincount(inv, x, minlength=k)
        N, S1 = draws @ n, draws @ s1
        if stat == "mean":
            boots = S1 / N
        else:
            S2 = draws @ np.bincount(inv, x * x, minlength=k)
            if stat == "rms":
                boots = np.sqrt(S2 / N)
            else:
                with np.errstate(invalid="ignore", divide="ignore"):
                    boots = np.sqrt(np.clip(S2 - S1 * S1 / N, 0, None) / (N - 1))
                boots[N < 2] = np.nan
    else:
        rows = np.arange(len(x))
        boots = np.array([fn(x[np.repeat(rows, d[inv])]) for d in draws], dtype=float)
    return _percentile_interval(est, boots, confidence, len(x), k, method)


def _cluster_draws(g: np.random.Generator, k: int, n_boot: int) -> np.ndarray:
    """(n_boot, k) multinomial cluster counts: k clusters drawn uniformly with replacement per resample."""
    pick = g.integers(0, k, size=(n_boot, k)) + (k * np.arange(n_boot))[:, None]
    return np.bincount(pick.ravel(), minlength=n_boot * k).reshape(n_boot, k)


def _percentile_interval(est: float, boots: np.ndarray, confidence: float, n: int, k: int, method: str) -> Interval:
    boots = boots[np.isfinite(boots)]
    if len(boots) == 0:
        return Interval(est, np.nan, np.nan, n, k, method)
    a = 100.0 * (1.0 - confidence) / 2.0
    lo, hi = np.percentile(boots, [a, 100.0 - a])
    return Interval(est, float(lo), float(hi), n, k, method)


def cluster_mean_bootstrap(counts, sums, *, confidence: float = 0.95, n_boot: int = 2000, rng=None,
                           cluster_name: str = "clusters") -> Interval:
    """:func:`cluster_bootstrap` of the mean from per-cluster row counts and sums (clusters in sorted label order,
    NaN rows already left out): the same resamples and, for sums made as ``np.bincount`` of the rows, the same
    limits; the estimate is Σ sums / Σ counts. Clusters with no rows are dropped."""
    n = np.asarray(counts, float).ravel()
    s1 = np.asarray(sums, float).ravel()
    keep = n > 0
    n, s1 = n[keep], s1[keep]
    method = f"cluster bootstrap (percentile, {n_boot} resamples, clusters = {cluster_name})"
    k, rows = len(n), int(n.sum())
    if k == 0:
        return Interval(np.nan, np.nan, np.nan, 0, 0, method)
    est = float(s1.sum() / n.sum())
    if k < 2:
        return Interval(est, np.nan, np.nan, rows, k, method)
    draws = _cluster_draws(_rng(rng), k, n_boot)
    return _percentile_interval(est, (draws @ s1) / (draws @ n), confidence, rows, k, method)


def cluster_bootstrap_rate(flags, clusters, *, confidence: float = 0.95, n_boot: int = 2000, rng=None,
                           cluster_name: str = "clusters") -> Interval:
    """Cluster-bootstrap interval of a proportion (the mean of a 0/1 variable).

    Parameters
    ----------
    flags : array_like of bool, shape (n,)
        True where the event happened (e.g. no result, gross error). A float array may carry NaN for
        rows where the event does not apply; they are dropped.
    clusters : array_like, shape (n,)
        Cluster label per row.
    confidence, n_boot, rng, cluster_name
        As in :func:`cluster_bootstrap`.

    Returns
    -------
    Interval
        Estimate and limits are proportions in [0, 1].
    """
    f = np.asarray(flags)
    f = f.astype(float) if f.dtype == bool else np.asarray(f, dtype=float)
    return cluster_bootstrap(f, clusters, "mean", confidence=confidence, n_boot=n_boot, rng=rng,
                             cluster_name=cluster_name)


def paired_difference(a, b, clusters, stat: Stat = "mean", *, confidence: float = 0.95, n_boot: int = 2000,
                      rng=None, cluster_name: str = "clusters") -> Interval:
    """Cluster-bootstrap interval of ``stat(a - b)`` over the rows where both are finite.

    Parameters
    ----------
    a, b : array_like, shape (n,)
        Paired values (e.g. ``|err_spc|`` and ``|err_retina|`` of the same row); rows where either is
        not finite are dropped.
    clusters : array_like, shape (n,)
        Cluster label per pair; clusters are resampled whole, so the pairing is kept.
    stat, confidence, n_boot, rng, cluster_name
        As in :func:`cluster_bootstrap`.

    Returns
    -------
    Interval
        Of the statistic of the differences; ``n`` counts the pairs used.
    """
    a = np.asarray(a, dtype=float).ravel()
    b = np.asarray(b, dtype=float).ravel()
    c = np.asarray(clusters).ravel()
    if not (a.shape == b.shape == c.shape):
        raise ValueError(f"a, b and clusters differ in length: {a.shape[0]}, {b.shape[0]}, {c.shape[0]}")
    ok = np.isfinite(a) & np.isfinite(b)
    return cluster_bootstrap(a[ok] - b[ok], c[ok], stat, confidence=confidence, n_boot=n_boot, rng=rng,
                             cluster_name=cluster_name)


def iid_interval(values, stat: str = "mean", confidence: float = 0.95) -> Interval:
    """Textbook interval assuming i.i.d. normal rows (for contrast with the cluster bootstrap).

    Parameters
    ----------
    values : array_like, shape (n,)
        NaNs are dropped.
    stat : {"mean", "std"}
        ``"mean"``: Student-t interval; ``"std"`` (ddof=1): χ² interval.
    confidence : float
        Two-sided confidence level.

    Returns
    -------
    Interval
        ``n_clusters`` equals ``n`` (every row its own cluster); NaN limits with fewer than 2 rows.
    """
    x = np.asarray(values, dtype=float).ravel()
    x = x[~np.isnan(x)]
    n = len(x)
    a = (1.0 - confidence) / 2.0
    if stat == "mean":
        method = "i.i.d. Student-t"
        est = float(np.mean(x)) if n else np.nan
        if n < 2:
            return Interval(est, np.nan, np.nan, n, n, method)
        h = float(_st.t.ppf(1.0 - a, n - 1) * np.std(x, ddof=1) / np.sqrt(n))
        return Interval(est, est - h, est + h, n, n, method)
    if stat == "std":
        method = "i.i.d. chi-square"
        if n < 2:
            return Interval(np.nan, np.nan, np.nan, n, n, method)
        s = float(np.std(x, ddof=1))
        lo = s * np.sqrt((n - 1) / _st.chi2.ppf(1.0 - a, n - 1))
        hi = s * np.sqrt((n - 1) / _st.chi2.ppf(a, n - 1))
        return Interval(s, float(lo), float(hi), n, n, method)
    raise ValueError(f"iid_interval supports stat 'mean' or 'std', not {stat!r}")
