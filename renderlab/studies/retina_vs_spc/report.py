"""Report hooks of ``retina_vs_spc``: the pre-declared well-measured subset (``[retina_vs_spc].well_measured``) and
the gross-error threshold, read from the campaign's own scenario."""

from __future__ import annotations

import numpy as np

from renderlab.studies.retina_vs_spc.config import RetinaVsSpcConfig


def _config(scenario_dict: dict):
    return RetinaVsSpcConfig.model_validate(scenario_dict.get("retina_vs_spc") or {})


def well_measured_mask(table, cfg) -> np.ndarray:
    """GSD ratio in [min, max], truth shadow fraction ≤ max, truth visible (NaN covariates fail)."""
    def col(name):
        return np.asarray(table.column(name).to_numpy(zero_copy_only=False), float)

    w = cfg.well_measured
    g, sh = col("gsd_ratio"), col("shadow_fraction")
    vis = np.asarray(table.column("truth_visible").to_numpy(zero_copy_only=False), bool)
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
