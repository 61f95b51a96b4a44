"""Observable kinds as data: what a kind of measurement is made of, so a later step can register kinds.

The lab's first three kinds (``landmark``, ``filter``, ``pose``) are spelled out where they are used (the reason enums
of :mod:`.reasons`, the table schemas of :mod:`.schemas`, the report dispatch, the executor, the command-line plug-in
registration). A new kind is instead described by one :class:`ObservableKind` object that carries every part the lab
needs, by value or as a lazy ``"module:attr"`` reference (so the contracts stay free of pyarrow and of the estimators):

* ``reasons`` — the ``str`` enum of why a row has no result, ``ok`` first (the ``reason`` column);
* ``frame`` / ``result`` / ``protocol`` — what a method receives, what it returns, the ``typing.Protocol`` it follows;
* ``truth_table`` — the truth table a world writes for the kind (its schema in :mod:`.schemas`);
* ``result_schema``, ``conformance``, ``runner``, ``scorer``, ``report_section`` — references filled in as the kind
  gains them (None until then).

Design: a kind is *registered*, not edited in: the plan is a registry ``plugins.observables`` (name →
:class:`ObservableKind`, entry-point group ``renderlab.observables``) that the places listing kinds today read, the
lab's own kinds then described by the same object. This module only fixes the object; the first kind built on it is
``centre_limb`` (:data:`renderlab.contracts.centre_limb.CENTRE_LIMB`). :meth:`ObservableKind.check_result` applies the
rules every kind shares: a known reason, ``ok`` exactly with a result.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from typing import Any


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
        section, as they exist.
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
