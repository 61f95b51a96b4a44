"""Study registry: study name → run function.

A study is ``run(scenario, base_dir, run_index, seed_sequence, workdir) -> dict[str, pyarrow.Table]``:
it perturbs the scenario (``scenario.perturbations``), renders (through :mod:`renderlab.campaign.cache`,
under ``workdir``), runs the estimators and returns its tables. Measurement tables follow design.md
(``campaign, run, frame, item, method, pred_s, pred_l, meas_s, meas_l, truth_s, truth_l, err_s, err_l,
score, flags, t_ms`` + extras); filter tables ``run, t_s, err_r_m, ...``. The engine adds ``campaign``
and ``run`` if a table lacks them. Every random draw must come from ``seed_sequence``.

Register a study by adding ``name: "module:function"`` to :data:`STUDIES` (one module per study), or
name it directly in the scenario as ``campaign.study = "package.module:function"``.
"""

from __future__ import annotations

import importlib
from typing import Callable

from renderlab.errors import UserError

#: study name → "module:function" (imported lazily)
STUDIES: dict[str, str] = {
    "analytic_pointing": "renderlab.campaign.study_analytic:run",
    "retina_vs_spc": "renderlab.campaign.study_retina_spc:run",
    "coastline_ekf": "renderlab.studies.coastline_study:run",
    "unknown_satellite": "renderlab.studies.unknown_satellite_campaign:run",
}

#: world kind → the study a campaign runs when ``campaign.study`` is empty
DEFAULT_STUDY: dict[str, str] = {
    "analytic": "analytic_pointing",
    "ev5": "retina_vs_spc",
    "earth": "coastline_ekf",
    "microsat": "unknown_satellite",
}


def register_study(name: str, target: str, *, default_for: str | None = None) -> None:
    """Add ``name`` → ``"module:function"`` (optionally the default study of a world kind)."""
    STUDIES[name] = target
    if default_for:
        DEFAULT_STUDY[default_for] = name


def study_for(scenario) -> str:
    """The study named by ``scenario.campaign.study`` or the default of its world kind."""
    if scenario.campaign.study:
        return scenario.campaign.study
    kind = scenario.world.kind
    if kind not in DEFAULT_STUDY:
        raise UserError(f"no campaign study for world kind '{kind}' yet; set campaign.study "
                        f"(known: {', '.join(sorted(STUDIES))})")
    return DEFAULT_STUDY[kind]


def resolve_study(name: str) -> Callable:
    """The run function of a registered study name or a ``module:function`` reference."""
    target = STUDIES.get(name, name)
    if ":" not in target:
        raise UserError(f"campaign.study: unknown study '{name}' (known: {', '.join(sorted(STUDIES))}, "
                        "or 'module:function')")
    mod_name, _, fn_name = target.partition(":")
    try:
        module = importlib.import_module(mod_name)
    except ImportError as exc:
        raise UserError(f"campaign.study '{name}': cannot import {mod_name} ({exc})") from None
    fn = getattr(module, fn_name, None)
    if not callable(fn):
        raise UserError(f"campaign.study '{name}': {mod_name} has no function {fn_name}")
    return fn
