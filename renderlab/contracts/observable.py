"""Observable kinds as data: what a kind of measurement is made of, registered by name.

Every kind of observable the lab scores — its own ``landmark``, ``filter`` and ``pose``, the ``centre_limb`` kind, a
third party's — is one :class:`ObservableKind` object registered in :data:`renderlab.plugins.observables` (name →
kind; entry-point group ``renderlab.observables``). Every place that needs "the kinds" reads that registry: the
``reason`` enums (:func:`renderlab.contracts.reasons.reason_values`), the table schemas and table-kind detection
(:mod:`.schemas`), the campaign executor's table checks, the report's per-kind sections, ``--plugin`` and
``renderlab check-method KIND METHOD``. Adding a kind is registering one object, never editing a list of kinds.

A kind carries every part by value or as a lazy ``"module:attr"`` reference (the contracts stay free of pyarrow and of
the estimators); the lab calls the references with these signatures:

========================  ==========================================================================================
field                     used as
========================  ==========================================================================================
``reasons``               ``str`` enum of why a row has no result, ``ok`` first (the ``reason`` column)
``frame``, ``result``     what a method receives / returns (``result.reason``, ``result.has_result``)
``protocol``              the ``typing.Protocol`` its methods follow: a class with every method the protocol declares
                          is a method of the kind (``--plugin``, :func:`renderlab.plugins.kind_of_method`)
``result_schema``         ``pyarrow.Schema``: the columns every table of the kind has (table-kind detection: a table
                          holding all of them is of the kind; the kind with the most such columns wins)
``known_schema``          ``pyarrow.Schema``: every column the kind's readers know, typed (default ``result_schema``)
``table_names``           table names that are always of the kind (a study's ``measurements`` is a landmark table)
``methods``               entry-point group of its methods (default ``renderlab.<name>_methods``), the registry
                          :func:`renderlab.plugins.method_registry` returns
``runner``                ``runner(method, frames) -> list[dict]``: one row per result, the table's columns
                          (:func:`renderlab.measurement.kinds.measure_frames` types and checks the table)
``scorer``                ``scorer(table, *, confidence=0.95) -> list[dict]``: summary rows
                          (:func:`renderlab.campaign.scoring.score_table`)
``report_section``        ``report_section(name, table, out_dir, context: ReportContext) -> (section, summary_rows,
                          headline)``: one section of ``renderlab report`` (``section`` a dict ``title``, ``anchor``,
                          ``blocks``; ``summary_rows`` go to ``summary.csv``; ``headline`` "" or one line)
``conformance``           ``conformance(factory) -> list[str]``: the kind's harness, one line per broken rule naming
                          it, empty when the method conforms (``renderlab check-method KIND METHOD``)
========================  ==========================================================================================

A reference left None means the kind lacks that part (no generic section, no harness); the lab then skips it.
:meth:`ObservableKind.check_result` applies the rules every kind shares: a known reason, ``ok`` exactly with a result.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from typing import Any

from renderlab.contracts.refs import load


@dataclass(frozen=True)
class ObservableKind:
    """One kind of observable (module docstring).

    Attributes
    ----------
    name : str
        Registry name, also the ``kind`` of its tables.
    description : str
        One line for reports.
    reasons : type of Enum
        ``str`` enum of no-result reasons, ``ok`` first, then in priority order.
    frame, result, protocol : type
        Input dataclass, result dataclass (with ``reason`` and a ``has_result`` property), method protocol.
    truth_table : str
        Name of the truth table a world writes for the kind ("" when none).
    result_schema, conformance, runner, scorer, report_section : str or None
        ``"module:attr"`` references of the kind's result-table schema, conformance harness, runner, scorer and report
        section, as they exist (signatures in the module docstring).
    known_schema : str or None
        ``"module:attr"`` of every column the kind's readers know (None: ``result_schema``).
    table_names : tuple of str
        Campaign table names that are always of this kind.
    methods : str
        Entry-point group of the kind's methods ("": ``renderlab.<name>_methods``).
    """

    name: str
    description: str
    reasons: type[Enum]
    frame: type
    result: type
    protocol: type
    truth_table: str = ""
    result_schema: str | None = None
    conformance: str | None = None
    runner: str | None = None
    scorer: str | None = None
    report_section: str | None = None
    known_schema: str | None = None
    table_names: tuple[str, ...] = ()
    methods: str = ""

    @property
    def method_group(self) -> str:
        """The entry-point group of the kind's methods."""
        return self.methods or f"renderlab.{self.name}_methods"

    def part(self, field: str) -> Any:
        """The object a reference field names (loaded), or None when the kind lacks it."""
        ref = getattr(self, field)
        return None if ref is None else load(ref)

    def core_schema(self):
        """The columns every table of the kind has (``pyarrow.Schema``), or None."""
        return self.part("result_schema")

    def known_columns(self):
        """Every column the kind's readers know (``pyarrow.Schema``), or None."""
        return self.part("known_schema") if self.known_schema is not None else self.core_schema()

    def reason_values(self) -> tuple[str, ...]:
        """The allowed ``reason`` strings, in priority order."""
        return tuple(r.value for r in self.reasons)

    def check_result(self, result: Any, where: str = "") -> None:
        """Raise ``ValueError`` when ``result`` has an unknown reason or ``ok`` without a result (or the reverse)."""
        reason = getattr(result, "reason", None)
        if not isinstance(reason, str) or reason not in self.reason_values():
            raise ValueError(f"{where}{self.name}: reason {reason!r} is not one of {', '.join(self.reason_values())}")
        ok = reason == self.reason_values()[0]
        if bool(result.has_result) != ok:
            raise ValueError(f"{where}{self.name}: has_result={bool(result.has_result)} but reason={reason!r}: a "
                             f"missing result needs a reason, a result needs '{self.reason_values()[0]}'")


@dataclass(frozen=True)
class ReportContext:
    """What a kind's ``report_section`` is told beside its table.

    Attributes
    ----------
    study : object or None
        The campaign's registered :class:`~renderlab.contracts.study.Study` (its hooks: ``subsets``, ``clusters``...).
    scenario : dict
        The campaign's scenario.
    confidence : float
        Confidence level of the intervals.
    """

    study: Any = None
    scenario: dict | None = None
    confidence: float = 0.95
