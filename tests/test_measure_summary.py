"""The ``renderlab measure`` summary line states a robust location (the median) beside the robust σ, the mean only
without gross errors (their count said) or labelled as the mean of all results. Oracle: numpy on hand-made errors
with one wild match, the case where the mean (+0.99 px here) says nothing about the typical error (median −0.01 px)."""

from __future__ import annotations

import re

import numpy as np
import pyarrow as pa

from renderlab.commands.measure import summary_line

ERR_S = [0.02, -0.01, -0.03, 0.01, -0.02, 6.0]  # one gross error on the sample axis
ERR_L = [0.05, 0.04, 0.06, 0.03, 0.07, 0.05]


def _table(es, el, has):
    return pa.table({"has_result": pa.array(has), "err_s": pa.array(es, pa.float64()),
                     "err_l": pa.array(el, pa.float64())})


def _number(line: str, label: str) -> float:
    m = re.search(re.escape(label) + r" ([+-]?\d+\.\d+) px", line)
    assert m, f"{label!r} not in {line!r}"
    return float(m.group(1))


def test_summary_is_robust_and_says_what_it_excluded():
    es, el = ERR_S + [np.nan], ERR_L + [np.nan]
    line = summary_line(_table(es, el, [True] * 6 + [False]))
    s, l_ = np.array(ERR_S), np.array(ERR_L)
    assert line.startswith("6/7 with a result; 1 gross error (|err| > 1 px) excluded from the mean")
    part_s, part_l = line.split("; ")[2:4]
    assert abs(_number(part_s, "sample median") - np.median(s)) <= 5e-4
    mad = np.median(np.abs(s - np.median(s)))
    assert abs(_number(part_s, "robust sigma") - 1.4826 * mad) <= 5e-4
    assert abs(_number(part_s, "mean without gross errors") - s[:5].mean()) <= 5e-4
    assert abs(_number(part_s, "mean of all results") - s.mean()) <= 5e-4  # +0.995: labelled, not called a bias
    assert abs(_number(part_l, "line median") - np.median(l_)) <= 5e-4
    assert abs(_number(part_l, "mean without gross errors") - l_[:5].mean()) <= 5e-4  # the row is gross on s
    assert "bias" not in line


def test_summary_without_results():
    line = summary_line(_table([np.nan] * 3, [np.nan] * 3, [False] * 3))
    assert line == "0/3 with a result"


def test_summary_all_gross():
    line = summary_line(_table([3.0, -4.0], [0.0, 0.0], [True, True]))
    assert "2 gross errors" in line and "mean without gross errors n/a" in line
