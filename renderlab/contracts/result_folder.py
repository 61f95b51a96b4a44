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

Figures: every figure of every report goes through one writer, :func:`save_figure`: a 100-dpi palette PNG
(at most 256 colours, no metadata, so the same figure gives the same bytes) and, only inside :func:`with_svg`
(``renderlab report --svg``), an SVG beside it. Inside :func:`tables_only` (``renderlab report --tables-only``)
:func:`figures_wanted` is False and every report — the campaign report and each kind's ``write_report`` — writes
its tables and text (CSV, Markdown, HTML) but no figure: the quick check that a published folder's numbers still
follow from its tables.
"""

from __future__ import annotations

import contextlib
import contextvars
from pathlib import Path
from typing import Iterator, Protocol, runtime_checkable

_FIGURES: contextvars.ContextVar[bool] = contextvars.ContextVar("renderlab_report_figures", default=True)
_SVG: contextvars.ContextVar[bool] = contextvars.ContextVar("renderlab_report_svg", default=False)

#: resolution of every report figure (dots per inch of matplotlib's figure size)
FIGURE_DPI = 100
#: colours of the PNG palette (Pillow's median cut on the anti-aliased RGB image, no dithering)
PALETTE_COLOURS = 256


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


def svg_wanted() -> bool:
    """Whether reports also write an SVG of each figure (True inside :func:`with_svg`)."""
    return _SVG.get()


@contextlib.contextmanager
def with_svg() -> Iterator[None]:
    """Within the block, :func:`save_figure` writes ``<stem>.svg`` beside each PNG (``renderlab report --svg``)."""
    token = _SVG.set(True)
    try:
        yield
    finally:
        _SVG.reset(token)


def figure_png(fig, *, dpi: int = FIGURE_DPI) -> bytes:
    """The bytes of ``fig`` as a palette PNG: drawn by matplotlib's Agg at ``dpi``, reduced to at most
    :data:`PALETTE_COLOURS` colours (median cut, no dithering) and written by Pillow with no text chunk, time or
    physical size, so the same figure gives the same bytes on every run."""
    import io

    from PIL import Image

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, metadata={"Software": None})
    buf.seek(0)
    with Image.open(buf) as rgba:
        rgb = Image.new("RGB", rgba.size, (255, 255, 255))
        rgb.paste(rgba, mask=rgba.getchannel("A"))  # a transparent pixel reads as the white page
    pal = rgb.quantize(colors=PALETTE_COLOURS, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
    out = io.BytesIO()
    pal.save(out, format="PNG", optimize=True)
    return out.getvalue()


def save_figure(fig, path_stem: Path) -> list[str | None]:
    """The one figure writer of the lab: ``<stem>.png`` (:func:`figure_png`) and, inside :func:`with_svg`,
    ``<stem>.svg``; closes ``fig`` and returns the two file names (the SVG's None when none is written). Inside
    :func:`tables_only` nothing is drawn or written and the names are returned all the same."""
    import matplotlib.pyplot as pyplot

    stem = Path(path_stem)
    png, svg = stem.with_suffix(".png"), stem.with_suffix(".svg")
    try:
        if figures_wanted():
            png.write_bytes(figure_png(fig))
            if svg_wanted():
                with pyplot.rc_context({"svg.hashsalt": "renderlab"}):  # element ids the same from run to run
                    fig.savefig(svg, format="svg", dpi=FIGURE_DPI, metadata={"Date": None})
    finally:
        pyplot.close(fig)
    return [png.name, svg.name if svg_wanted() else None]


@runtime_checkable
class ResultFolderKind(Protocol):
    """A kind of result folder (module docstring)."""

    name: str

    def recognises(self, folder: Path) -> bool:
        """Whether ``folder`` is of this kind (its marker file is there)."""

    def write_report(self, folder: Path, out_dir: Path | None) -> list[Path]:
        """Regenerate the report of ``folder`` into ``out_dir`` (``None``: the kind's default place, usually
        inside ``folder``) from its tables alone; the written files."""
