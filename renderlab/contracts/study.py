"""The study contract: what a campaign runs, how its tables are reported, and its scenario section.

A study is registered (``renderlab.plugins.studies``, entry-point group ``renderlab.studies``) as a
:class:`Study`. ``run(scenario, base_dir, run_index, seed_sequence, workdir) -> {table_name: pyarrow.Table}``
perturbs the scenario (``scenario.perturbations``), renders through the truth cache under ``workdir``, runs the
estimators and returns tables of the kinds in :mod:`renderlab.contracts.schemas`. Every random draw comes from
``seed_sequence``. The engine adds ``campaign`` and ``run`` if a table lacks them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

from renderlab.contracts.refs import lazy  # noqa: F401  (re-exported: studies register with it)


@dataclass(frozen=True)
class Study:
    """A registered study.

    Attributes
    ----------
    name : str
        Registry name (``campaign.study`` in a scenario).
    run : callable
        One Monte Carlo run (module docstring).
    worlds : tuple of str
        World kinds the study can run on; the first study listing a kind is its default.
    description : str
        One line for listings and reports.
    report_sections : callable or None
        ``(tables, out_dir) -> [(title, html)]`` for the study's own report sections.
    demo : callable or None
        The study's piece of ``renderlab demo``.
    check : callable or None
        ``check(scenario)`` raising :class:`~renderlab.errors.UserError` for what the study cannot run; called
        when the campaign plan is made, before any output exists.
    """

    name: str
    run: Callable[..., dict]
    worlds: tuple[str, ...]
    description: str = ""
    report_sections: Callable[..., list] | None = None
    demo: Callable[..., Any] | None = None
    check: Callable[..., None] | None = None  #: ``check(scenario)``: refuse what the study cannot run, before any output
    subsets: Callable[..., list] | None = None  #: ``subsets(table, scenario_dict) -> [(key, mask, label)]``
    gross_error_px: Callable[..., float] | None = None  #: ``gross_error_px(scenario_dict) -> px``
    clusters: tuple[str, ...] = ("frame", "item")  #: columns whose rows are correlated (cluster-bootstrap units)
    own_tables: tuple[str, ...] = ()  #: tables ``report_sections`` reports itself (the generic sections skip them)
    #: ``publish_tables(tables) -> tables``: the tables a published folder ships — what the report reads, at full
    #: precision (:mod:`renderlab.campaign.compact`); None: every table whole
    publish_tables: Callable[[dict], dict] | None = None
