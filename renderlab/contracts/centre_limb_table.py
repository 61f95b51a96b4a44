"""The result table of the centre/limb kind (``kind = "centre_limb"``): one row per image and method.

Core columns (:data:`CENTRE_LIMB_CORE`, every table of the kind has them; :mod:`renderlab.contracts.centre_limb` for
the quantities and conventions):

* identity: ``campaign``, ``run``, ``frame``, ``cell`` (the grid cell a study rendered the image for: the cluster of
  correlated rows), ``method``;
* result: ``has_result``, ``reason`` (a :class:`~renderlab.contracts.centre_limb.CentreLimbReason`), ``diagnostics``,
  ``t_ms``; the centre ``centre_s``, ``centre_l`` (px) and its covariance ``cov_ss``, ``cov_sl``, ``cov_ll`` (px²);
  the limb ellipse ``limb_centre_s``, ``limb_centre_l``, ``limb_a_px``, ``limb_b_px``; ``n_limb_points``; the
  camera-to-body vector ``r_x``, ``r_y``, ``r_z`` (camera frame, m), ``range_m``, and its covariance ``cov_r_xx``,
  ``cov_r_xy``, ``cov_r_xz``, ``cov_r_yy``, ``cov_r_yz``, ``cov_r_zz`` (m²); NaN where the method does not give one;
* truth of the image (the ``centre_truth`` row of the rendered pose): ``true_centre_s``, ``true_centre_l``,
  ``true_limb_centre_s``, ``true_limb_centre_l``, ``true_radius_px``, ``true_range_m``, ``true_los_x``,
  ``true_los_y``, ``true_los_z``, ``phase_deg``; the camera's ``fx`` (px), for angles.

Studies add their grid columns (:data:`CENTRE_LIMB_KNOWN`: ``law``, ``range_nominal_m``, ``phase_nominal_deg``,
``draw``).
"""

from __future__ import annotations

import pyarrow as pa

F64, I64, STR, BOOL = pa.float64(), pa.int64(), pa.string(), pa.bool_()
REASON = pa.dictionary(pa.int32(), pa.string())

#: result columns of one measurement (the names of :func:`renderlab.measurement.centre_limb_runner.result_row`)
RESULT_COLUMNS = ("centre_s", "centre_l", "cov_ss", "cov_sl", "cov_ll", "limb_centre_s", "limb_centre_l",
                  "limb_a_px", "limb_b_px", "r_x", "r_y", "r_z", "range_m", "cov_r_xx", "cov_r_xy", "cov_r_xz",
                  "cov_r_yy", "cov_r_yz", "cov_r_zz")
#: truth columns copied from the image's ``centre_truth`` row
TRUTH_COLUMNS = ("true_centre_s", "true_centre_l", "true_limb_centre_s", "true_limb_centre_l", "true_radius_px",
                 "true_range_m", "true_los_x", "true_los_y", "true_los_z", "phase_deg", "fx")

CENTRE_LIMB_CORE = pa.schema([
    ("campaign", STR), ("run", I64), ("frame", I64), ("cell", I64), ("method", STR), ("has_result", BOOL),
    ("reason", REASON), ("diagnostics", STR), ("t_ms", F64), *[(c, F64) for c in RESULT_COLUMNS],
    ("n_limb_points", I64), *[(c, F64) for c in TRUTH_COLUMNS],
])

CENTRE_LIMB_KNOWN = pa.schema(list(CENTRE_LIMB_CORE) + [
    ("law", STR), ("range_nominal_m", F64), ("phase_nominal_deg", F64), ("draw", I64),
])
