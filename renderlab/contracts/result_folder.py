"""The result-folder contract: a kind of published folder that ``renderlab report FOLDER`` regenerates.

Most studies publish in the campaign layout (``tables/``, ``campaign.json``, ``runs.json``; the lab's own
campaign report, :mod:`renderlab.campaign.publish`). A folder of another shape — a ``renderlab crosscheck``
folder, an error budget made of many campaigns — registers a *result-folder kind* in the ``result_folders``
registry (:mod:`renderlab.plugins`, entry-point group ``renderlab.result_folders``). ``renderlab report`` asks
each registered kind, in name order, whether it :meth:`~ResultFolderKind.recognises` the folder, and the first
that does writes the report from the folder's committed tables alone.

Rules: ``recognises`` only looks for the kind's marker file (cheap, no table read); ``write_report`` validates
the tables before it creates any output, writes staged (all or nothing) and raises
:class:`~renderlab.errors.UserError` (one line) for a missing or unreadable table.

Figures: inside :func:`tables_only` (``renderlab report --tables-only``) :func:`figures_wanted` is False and every
report — the campaign report and each kind's ``write_report`` — writes its tables and text (CSV, Markdown, HTML)
but no PNG or SVG: the quick check that a published folder's numbers still follow from its tables.
"""

from __future__ import annotations

import contextlib
import contextvars
from pathlib import Path
from typing import Iterator, Protocol, runtime_checkable

_FIGURES: contextvars.ContextVar[bool] = contextvars.ContextVar("renderlab_report_figures", default=True)


def figures_wanted() -> bool:
    """Whether reports draw their figures (False inside :func:`tables_only`)."""
    return _FIGURES.get()


@contextlib.contextmanager
def tables_only() -> Iterator[None]:
    """Within the block, reports write their tables and text only: no PNG or SVG is drawn (module docstring)."""
    token = _FIGURES.set(False)
    try:
        yield
    finally:
        _FIGURES.reset(token)


@runtime_checkable
class ResultFolderKind(Protocol):
    """A kind of result folder (module docstring)."""

    name: str

    def recognises(self, folder: Path) -> bool:
        """Whether ``folder`` is of this kind (its marker file is there)."""

    def write_report(self, folder: Path, out_dir: Path | None) -> list[Path]:
        """Regenerate the report of ``folder`` into ``out_dir`` (``None``: the kind's default place, usually
        inside ``folder``) from its tables alone; the written files."""
