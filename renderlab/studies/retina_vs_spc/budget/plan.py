"""The configurations of the error budget (:mod:`.runner`): its sources and the scenario keys that switch each on,
"every source off", the methods, and the tables kept; the configurations themselves are built by the generic
one-at-a-time core (:func:`renderlab.campaign.oat_budget.oat_configs`: one source on alone, all off, all on, plus
``no_shadows``)."""

from __future__ import annotations

import copy

from renderlab.campaign.oat_budget import has_draws, oat_configs
from renderlab.campaign.oat_tables import OatTables
from renderlab.studies.retina_vs_spc.budget import shadows as SH
from renderlab.studies.retina_vs_spc.config import RetinaVsSpcConfig

#: source → (description, dotted scenario keys restored from the base scenario to switch it on)
SOURCES: dict[str, tuple[str, tuple[str, ...]]] = {
    "sensor_noise": ("sensor noise (Poisson + read noise, new draw per run)", ("retina_vs_spc.sensor_noise",)),
    "mapping_error": ("maplet mapping (height) error", ("world.mapping_error_m",)),
    "albedo_error": ("maplet albedo error", ("world.albedo_error_rms",)),
    "photometric_law": ("photometric law: Hapke truth vs the onboard McEwen fit", ("world.law", "world.law_params")),
    "apriori_pose": ("a-priori pose error", ("perturbations.apriori_position_sigma_m",
                                             "perturbations.apriori_attitude_sigma_deg")),
    "camera_knowledge": ("camera knowledge (focal length, principal point, distortion)",
                         ("perturbations.focal_length_sigma_frac", "perturbations.principal_point_sigma_px",
                          "perturbations.distortion_sigma")),
    "sun_knowledge": ("Sun-direction knowledge", ("perturbations.sun_direction_sigma_deg",)),
    "maplet_spacing": ("maplet resolution (spacing) knowledge", ("perturbations.maplet_spacing_sigma_frac",)),
}

#: every source off
OFF: dict[str, object] = {
    "retina_vs_spc.sensor_noise": False, "world.mapping_error_m": 0.0, "world.albedo_error_rms": 0.0,
    "world.law": "mcewen", "world.law_params": {},
    "perturbations.apriori_position_sigma_m": [0.0, 0.0, 0.0], "perturbations.apriori_attitude_sigma_deg": 0.0,
    "perturbations.focal_length_sigma_frac": 0.0, "perturbations.principal_point_sigma_px": 0.0,
    "perturbations.distortion_sigma": {}, "perturbations.sun_direction_sigma_deg": 0.0,
    "perturbations.maplet_spacing_sigma_frac": 0.0,
}

#: the methods of every configuration (the study's registered names)
METHODS = ("retina", "retina_refined", "retina_ml", "spc", "ncc_baseline")

#: the budget's terms in the order of its tables and figure
TERMS_ORDER = ("all_off", "sensor_noise", "mapping_error", "albedo_error", "photometric_law", "apriori_pose",
               "camera_knowledge", "sun_knowledge", "maplet_spacing", "peak_step", "shadow_approximation",
               "quadrature_sum", "all_on")

#: the measurement columns kept, and the truth columns a ``--methods`` run must reproduce
BUDGET_TABLES = OatTables(
    columns=("config", "run", "frame", "item", "method", "peak", "truth_s", "truth_l", "err_s", "err_l", "has_result",
             "reason", "outlier", "truth_visible", "score", "search_px", "n_pixels", "gsd_ratio", "phase_deg",
             "shadow_fraction", "pred_shadow_fraction", "crlb_s", "crlb_l", "range_m"),
    paired=("truth_s", "truth_l", "truth_visible", "gsd_ratio", "phase_deg", "shadow_fraction", "crlb_s", "crlb_l",
            "range_m"),
    make="python -m renderlab.studies.retina_vs_spc.budget run")

#: the columns a published budget folder ships (what its report, the navigation budget and a ``--methods`` merge
#: read); the tables not named are kept whole
PUBLISHED_COLUMNS = {
    "budget_measurements": ("config", "run", "frame", "item", "method", "truth_s", "truth_l", "err_s", "err_l",
                            "has_result", "reason", "truth_visible", "gsd_ratio", "phase_deg", "shadow_fraction",
                            "crlb_s", "crlb_l", "range_m"),
    "budget_navigation": ("mapping", "config", "method", "run", "err_e_m", "err_n_m", "err_u_m", "err_norm_m",
                          "track_lost", "diverged")}


def publish_tables(tables: dict) -> dict:
    """The tables of a published budget folder: :data:`PUBLISHED_COLUMNS` of the two large ones, the rest whole."""
    from renderlab.campaign.compact import keep_columns

    return keep_columns(tables, {k: v for k, v in PUBLISHED_COLUMNS.items() if k in tables})


def method_order(names) -> list:
    """The distinct method names in the budget's order: ``retina``, ``retina_refined``, then the rest sorted."""
    return sorted(set(names), key=lambda m: (m != "retina", m != "retina_refined", m))


def with_section(base: dict) -> dict:
    """A copy of the scenario dict with its ``[retina_vs_spc]`` section filled in (defaults when absent)."""
    base = copy.deepcopy(base)
    if not base.get("retina_vs_spc"):
        base["retina_vs_spc"] = RetinaVsSpcConfig().model_dump(mode="json")
    return base


def budget_configs(base: dict, methods=METHODS) -> list[dict]:
    """:func:`renderlab.campaign.oat_budget.oat_configs` of the budget (plus ``no_shadows``, :mod:`.shadows`) for a
    validated scenario's dict ``base``; every configuration names ``methods``."""
    return oat_configs(with_section(base), SOURCES, OFF, fixed={"retina_vs_spc.methods": list(methods)},
                       extra=((SH.CONFIG, SH.DESCRIPTION, SH.OVERRIDES),),
                       all_off="every source off (peak step: see retina vs retina_refined)",
                       all_on="every source on (the published campaign's scenario)",
                       need="an EV5 retina_vs_spc scenario with its [retina_vs_spc] section is needed")


def stochastic(sc: dict) -> bool:
    """Whether runs of the scenario differ (sensor noise on or a perturbation with non-zero σ)."""
    return has_draws(sc, ["retina_vs_spc.sensor_noise",
                          *(k for _, ks in SOURCES.values() for k in ks if k.startswith("perturbations."))])
