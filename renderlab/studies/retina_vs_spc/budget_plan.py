"""The configurations of the error budget (:mod:`.budget`): its sources and the scenario keys that switch each on,
"every source off", and the scenario of each configuration (one source on alone, all off, all on, no shadows)."""

from __future__ import annotations

import copy

from renderlab.errors import UserError
from renderlab.studies.retina_vs_spc import budget_shadows as SH
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


def _get(d: dict, dotted: str):
    for k in dotted.split("."):
        d = d[k]
    return d


def _set(d: dict, dotted: str, value) -> None:
    *head, last = dotted.split(".")
    for k in head:
        d = d.setdefault(k, {})
    d[last] = copy.deepcopy(value)


def with_section(base: dict) -> dict:
    """A copy of the scenario dict with its ``[retina_vs_spc]`` section filled in (defaults when absent)."""
    base = copy.deepcopy(base)
    if not base.get("retina_vs_spc"):
        base["retina_vs_spc"] = RetinaVsSpcConfig().model_dump(mode="json")
    return base


def budget_configs(base: dict, methods=METHODS) -> list[dict]:
    """The configurations: ``all_off``, one per source (that source at the base value, the others off) and
    ``all_on`` (the base scenario) → ``[{"config", "source", "description", "overrides", "scenario"}]``.

    ``base`` is a validated scenario's dict (defaults filled in); every configuration names ``methods``.
    """
    base = with_section(base)
    for keys in (k for _, ks in SOURCES.values() for k in ks):
        try:
            _get(base, keys)
        except (KeyError, TypeError):
            raise UserError(f"error budget: the base scenario has no {keys} (an EV5 retina_vs_spc scenario with "
                            "its [retina_vs_spc] section is needed)") from None
    out = []

    def add(name, source, desc, overrides):
        sc = copy.deepcopy(base)
        for k, v in overrides.items():
            _set(sc, k, v)
        _set(sc, "retina_vs_spc.methods", list(methods))
        out.append({"config": name, "source": source, "description": desc, "overrides": overrides, "scenario": sc})

    add("all_off", "", "every source off (peak step: see retina vs retina_refined)", dict(OFF))
    for src, (desc, keys) in SOURCES.items():
        add(src, src, f"{desc} alone", {**OFF, **{k: _get(base, k) for k in keys}})
    add("all_on", "", "every source on (the published campaign's scenario)", {})
    add(SH.CONFIG, "", SH.DESCRIPTION, {**OFF, **SH.OVERRIDES})     # the shadow term, at all off (.budget_shadows)
    return out


def stochastic(sc: dict) -> bool:
    """Whether runs of the scenario differ (sensor noise on or a perturbation with non-zero σ)."""
    if _get(sc, "retina_vs_spc.sensor_noise"):
        return True
    p = sc.get("perturbations") or {}
    keys = [k.split(".", 1)[1] for _, ks in SOURCES.values() for k in ks if k.startswith("perturbations.")]
    return any(_nonzero(p.get(k)) for k in keys)


def _nonzero(v) -> bool:
    if isinstance(v, dict):
        return any(_nonzero(x) for x in v.values())
    if isinstance(v, (list, tuple)):
        return any(_nonzero(x) for x in v)
    return v is not None and float(v) != 0.0
