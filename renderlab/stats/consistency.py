"""Helpers of filter-consistency scores over the lab's filter tables (:mod:`renderlab.contracts.schemas`): numpy
columns of a table, the χ² band of a sum of NIS/NEES values, the runs that kept track."""

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


def tracked(ftab):
    """The rows of the runs (per method) that never lost track — where filter consistency is defined; the runs that
    lost track are counted apart (``track_lost_runs``)."""
    import pyarrow as pa
    import pyarrow.compute as pc

    lost = ftab.filter(pc.field("track_lost"))
    bad = {(m, r) for m, r in zip(lost.column("method").to_pylist(), lost.column("run").to_pylist())}
    keys = zip(ftab.column("method").to_pylist(), ftab.column("run").to_pylist())
    return ftab.filter(pa.array([k not in bad for k in keys]))
