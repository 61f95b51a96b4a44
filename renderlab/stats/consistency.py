"""Helpers of filter-consistency scores over the lab's filter tables (:mod:`renderlab.contracts.schemas`): numpy
columns of a table, the χ² band of a sum of NIS/NEES values and of a run average, the runs that kept track."""

from __future__ import annotations

import math

import numpy as np


def columns(table, names) -> dict:
    """``{name: numpy array}`` of the columns ``names`` of a pyarrow table."""
    return {n: np.asarray(table.column(n).to_numpy(zero_copy_only=False)) for n in names}


def chi2_band_sum(dof_total: float) -> tuple[float, float]:
    """95 % band of (Σ χ²)/Σ dof for a total of ``dof_total`` degrees of freedom."""
    from scipy.stats import chi2

    if dof_total <= 0:
        return math.nan, math.nan
    return float(chi2.ppf(0.025, dof_total) / dof_total), float(chi2.ppf(0.975, dof_total) / dof_total)


def chi2_band_mean(dof_per_run, n_runs: int, p: float = 0.99) -> tuple[np.ndarray, np.ndarray]:
    """Two-sided ``p`` band of the average of ``n_runs`` χ²(dof) variables, per element of ``dof_per_run``:
    χ²_{(1∓p)/2}(N·dof)/N (NaN where dof = 0)."""
    from scipy.stats import chi2

    dof = np.asarray(dof_per_run, dtype=np.float64) * n_runs
    a = 0.5 * (1.0 - p)
    with np.errstate(invalid="ignore"):
        lo = np.where(dof > 0, chi2.ppf(a, np.maximum(dof, 1)) / n_runs, np.nan)
        hi = np.where(dof > 0, chi2.ppf(1.0 - a, np.maximum(dof, 1)) / n_runs, np.nan)
    return lo, hi


def chi2_sum_test(total: float, dof: float, p: float = 0.99) -> dict:
    """A sum ``total`` of χ² values of ``dof`` degrees of freedom in all against its two-sided ``p`` band of
    χ²(dof): ``total, dof, lo, hi, ratio`` (total / dof) and ``inside``."""
    from scipy.stats import chi2

    lo, hi = chi2.ppf(0.5 * (1 - p), dof), chi2.ppf(0.5 * (1 + p), dof)
    return {"total": total, "dof": dof, "lo": lo, "hi": hi, "ratio": total / dof, "inside": bool(lo <= total <= hi)}


def tracked(ftab):
    """The rows of the runs (per method) that never lost track — where filter consistency is defined; the runs that
    lost track are counted apart (``track_lost_runs``)."""
    import pyarrow as pa
    import pyarrow.compute as pc

    lost = ftab.filter(pc.field("track_lost"))
    bad = {(m, r) for m, r in zip(lost.column("method").to_pylist(), lost.column("run").to_pylist())}
    keys = zip(ftab.column("method").to_pylist(), ftab.column("run").to_pylist())
    return ftab.filter(pa.array([k not in bad for k in keys]))
