"""Report hooks of ``retina_vs_spc``: the pre-declared well-measured subset (``[retina_vs_spc].well_measured``) and
the gross-error threshold, read from the campaign's own scenario; the tables a published folder ships."""

from __future__ import annotations

import numpy as np

from renderlab.campaign.scoring import column_array
from renderlab.studies.retina_vs_spc.config import RetinaVsSpcConfig

#: the measurement columns the campaign report reads (:mod:`renderlab.report.landmark_section`: errors, truth, result,
#: reason, clusters and pairs, CRLB, the breakdown covariates; :func:`subsets`: GSD ratio, shadow, truth_visible)
PUBLISHED_COLUMNS = ("run", "frame", "item", "method", "truth_s", "truth_l", "err_s", "err_l", "has_result", "reason",
                     "truth_visible", "gsd_ratio", "phase_deg", "shadow_fraction", "range_m", "albedo_contrast",
                     "crlb_s", "crlb_l", "crlb_bound")


def _config(scenario_dict: dict):
    return RetinaVsSpcConfig.model_validate(scenario_dict.get("retina_vs_spc") or {})


def well_measured_mask(table, cfg) -> np.ndarray:
    """GSD ratio in [min, max], truth shadow fraction ≤ max, truth visible (NaN covariates fail)."""
    w = cfg.well_measured
    g, sh = column_array(table, "gsd_ratio"), column_array(table, "shadow_fraction")
    vis = column_array(table, "truth_visible", bool)
    return (g >= w.gsd_ratio_min) & (g <= w.gsd_ratio_max) & (sh <= w.shadow_fraction_max) & vis


def subsets(table, scenario_dict: dict) -> list:
    """[("well_measured", mask, label)] for the landmark section."""
    cfg = _config(scenario_dict)
    w = cfg.well_measured
    label = (f"Well-measured subset (declared in the scenario: {w.gsd_ratio_min:g} ≤ GSD ratio ≤ "
             f"{w.gsd_ratio_max:g}, shadow fraction ≤ {w.shadow_fraction_max:g}, landmark visible)")
    return [("well_measured", well_measured_mask(table, cfg), label)]


def gross_error_px(scenario_dict: dict) -> float:
    return float(_config(scenario_dict).gross_error_px)


def publish_tables(tables: dict) -> dict:
    """The published tables (:attr:`renderlab.contracts.study.Study.publish_tables`): ``measurements`` with the
    columns the report reads (:data:`PUBLISHED_COLUMNS`, ``crlb_bound`` where the table has it), the others whole."""
    from renderlab.campaign.compact import keep_columns

    t = tables.get("measurements")
    keep = [c for c in PUBLISHED_COLUMNS if t is None or c != "crlb_bound" or c in t.column_names]
    return keep_columns(tables, {"measurements": keep})
