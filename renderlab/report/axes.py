"""Robust axis limits for report figures: set by quantiles of what is drawn, never by one run's extreme sample, and
the points left outside counted on the plot.

A time series of 100 runs whose first image carries a large error (the filter's initial uncertainty) or one run
whose first sample is off by metres would otherwise set the scale of a whole panel and flatten everything else
(a panel reaching −4 m for errors of centimetres). :func:`symmetric_limit` takes the ``coverage`` quantile of
``|value|`` instead, with a margin, and :func:`typical_limit` the scale of a typical time of a time series;
:func:`note_outside` writes "k of N samples outside the axes" in the panel.
:func:`plain_log` (log axis, plain tick labels) and :func:`integer_ticks` set tick styles the studies share.
"""

from __future__ import annotations

import numpy as np


def symmetric_limit(values, coverage: float = 0.98, pad: float = 1.25, floor: float = 0.0) -> float:
    """Half-height of a panel centred on zero: ``pad`` × the ``coverage`` quantile of ``|values|`` (finite ones),
    at least ``floor``; 1.0 when there is nothing finite."""
    v = np.abs(np.asarray(values, float).ravel())
    v = v[np.isfinite(v)]
    if not v.size:
        return max(floor, 1.0)
    lim = pad * float(np.quantile(v, coverage))
    return max(lim, floor) if lim > 0 else max(floor, float(v.max()) or 1.0)


def typical_limit(values, groups, coverage: float = 0.98, of_groups: float = 0.8, pad: float = 1.2,
                  floor: float = 0.0) -> float:
    """Half-height of a panel of time series: ``pad`` × the ``of_groups`` quantile over groups (times) of each
    group's ``coverage`` quantile of ``|values|``, at least ``floor``: a scale that holds 98 % of the samples at 80 %
    of the times, so a transient (the first seconds of a filter, whose errors are 10× the rest) leaves the axes and
    is counted rather than flattening the panel, while a slow drift that lasts stays inside."""
    v, g = np.abs(np.asarray(values, float).ravel()), np.asarray(groups).ravel()
    ok = np.isfinite(v)
    per = [float(np.quantile(v[ok & (g == k)], coverage)) for k in np.unique(g[ok])]
    if not per:
        return max(floor, 1.0)
    lim = pad * float(np.quantile(per, of_groups))
    return max(lim, floor) if lim > 0 else symmetric_limit(values, coverage, pad, floor)


def limits(values, coverage: float = 0.98, pad: float = 0.1) -> tuple[float, float]:
    """(lo, hi) between the ``(1 − coverage)/2`` and ``(1 + coverage)/2`` quantiles, widened by ``pad`` of the span
    on each side."""
    v = np.asarray(values, float).ravel()
    v = v[np.isfinite(v)]
    if not v.size:
        return 0.0, 1.0
    lo, hi = (float(x) for x in np.quantile(v, [(1 - coverage) / 2, (1 + coverage) / 2]))
    span = hi - lo if hi > lo else max(abs(hi), 1.0)
    return lo - pad * span, hi + pad * span


def count_outside(values, lo: float, hi: float) -> tuple[int, int]:
    """(points outside [lo, hi], finite points)."""
    v = np.asarray(values, float).ravel()
    v = v[np.isfinite(v)]
    return int(np.sum((v < lo) | (v > hi))), int(v.size)


def note_outside(ax, values, lo: float, hi: float, what: str = "samples", where: str = "lower left",
                 times=None, time_unit: str = "s") -> int:
    """Write "k of N <what> outside the axes" in the panel when k > 0 (with ``times``: "all before t = T" when they
    all fall in the first quarter of the span); returns k."""
    v = np.asarray(values, float).ravel()
    k, n = count_outside(v, lo, hi)
    if k:
        text = f"{k} of {n} {what} outside the axes"
        if times is not None:
            t = np.asarray(times, float).ravel()
            out = np.isfinite(v) & ((v < lo) | (v > hi))
            t0, t1 = np.nanmin(t), np.nanmax(t)
            if t1 > t0 and np.nanmax(t[out]) <= t0 + 0.25 * (t1 - t0):
                text += f"\n(all before t = {np.nanmax(t[out]):.4g} {time_unit})"
        x, ha = (0.02, "left") if "left" in where else (0.98, "right")
        y, va = (0.02, "bottom") if "lower" in where else (0.98, "top")
        ax.text(x, y, text, transform=ax.transAxes, fontsize=7, ha=ha, va=va,
                bbox={"boxstyle": "round,pad=0.2", "fc": "white", "ec": "0.7", "alpha": 0.85})
    return k


def plain_log(ax, values=None, axis: str = "y") -> None:
    """Log scale with plain tick labels (0.5, 2, 10); with ``values``, only when they span more than a decade
    (else the axis stays linear)."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    if values is not None:
        v = np.asarray(values, float)
        v = v[np.isfinite(v) & (v > 0)]
        if len(v) < 2 or v.max() < 10 * v.min():
            return
    a = ax.yaxis if axis == "y" else ax.xaxis
    (ax.set_yscale if axis == "y" else ax.set_xscale)("log")
    a.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
    a.set_major_formatter(FuncFormatter(lambda x, _: f"{x:g}"))
    a.set_minor_formatter(NullFormatter())


def integer_ticks(ax, axis: str = "x") -> None:
    """Whole-number ticks on ``axis`` (counts: iterations, runs)."""
    from matplotlib.ticker import MaxNLocator

    (ax.xaxis if axis == "x" else ax.yaxis).set_major_locator(MaxNLocator(integer=True))
