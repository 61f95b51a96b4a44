"""One report style for every study: a colour-blind-safe palette with one colour per method everywhere, figures
saved by the lab's one figure writer (100-dpi palette PNG; SVG with ``renderlab report --svg``,
:func:`renderlab.contracts.result_folder.save_figure`), labels with units, pass/fail badges for banded quantities.

Palette: Okabe & Ito (2008), "Color Universal Design" — distinguishable under the common colour-vision
deficiencies. A method keeps its colour across every figure of a report (its index in the sorted method list).
"""

from __future__ import annotations

import html
import math
from pathlib import Path

from renderlab.contracts.result_folder import save_figure

OKABE_ITO = ("#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#F0E442", "#000000")

#: column → (label, unit) for axis labels and table headers; a raw column name never reaches a reader
LABELS = {
    "err_s": ("Δsample = measured − true", "px"), "err_l": ("Δline = measured − true", "px"),
    "range_m": ("range to landmark", "m"), "phase_deg": ("phase angle", "deg"), "gsd_ratio": ("GSD ratio", "—"),
    "shadow_fraction": ("shadow fraction", "—"), "albedo_contrast": ("albedo contrast", "—"),
    "incidence_deg": ("incidence angle", "deg"), "emission_deg": ("emission angle", "deg"),
    "t_s": ("time", "s"), "t_h": ("time", "h"),
}


def label(column: str) -> str:
    """``"phase angle (deg)"`` for a known column; otherwise the column with underscores as spaces and the unit
    taken from its suffix (``_m`` → m, ``_mps`` → m/s, ``_deg`` → deg, ``_px`` → px, ``_s`` → s)."""
    if column in LABELS:
        text, unit = LABELS[column]
        return f"{text} ({unit})" if unit != "—" else text
    units = {"_mps": "m/s", "_m": "m", "_deg_s": "deg/s", "_deg": "deg", "_px": "px", "_s": "s", "_rad": "rad",
             "_cm": "cm"}
    for suffix, unit in units.items():
        if column.endswith(suffix):
            return f"{column[: -len(suffix)].replace('_', ' ')} ({unit})"
    return column.replace("_", " ")


def method_colors(methods) -> dict[str, str]:
    """Method → colour, stable for a given set of methods (sorted order)."""
    return {m: OKABE_ITO[i % len(OKABE_ITO)] for i, m in enumerate(sorted(set(methods)))}


def plt():
    """matplotlib.pyplot on the Agg backend with the report's defaults (readable fonts, no clipping)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as pyplot

    pyplot.rcParams.update({"font.size": 10, "axes.titlesize": 10, "axes.labelsize": 10, "legend.fontsize": 9,
                            "xtick.labelsize": 9, "ytick.labelsize": 9,
                            "axes.formatter.useoffset": False})
    return pyplot


def save(fig, path_stem: Path) -> list[str | None]:
    """Save ``fig`` as ``<stem>.png`` (and ``<stem>.svg`` under ``renderlab report --svg``) through the lab's one
    figure writer, :func:`renderlab.contracts.result_folder.save_figure`; returns the PNG's and the SVG's file name
    (None when no SVG is written)."""
    return save_figure(fig, path_stem)


def badge(inside: bool | None, text: str = "") -> str:
    """An HTML pass/fail badge (``None``: not applicable)."""
    if inside is None or (isinstance(inside, float) and math.isnan(inside)):
        return '<span class="badge na">n/a</span>'
    cls, word = ("pass", "PASS") if inside else ("fail", "FAIL")
    return f'<span class="badge {cls}">{word}{" " + html.escape(text) if text else ""}</span>'


def fmt(v, digits: int = 4) -> str:
    """A table cell: floats to ``digits`` significant digits, NaN as an en dash, text escaped."""
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return "–" if math.isnan(v) else f"{v:.{digits}g}"
    return html.escape(str(v))


def ci(est: float, lo: float, hi: float, digits: int = 3, signed: bool = True) -> str:
    """``+0.051 [+0.009, +0.103]``."""
    if not math.isfinite(est):
        return "–"
    f = f"{{:+.{digits}f}}" if signed else f"{{:.{digits}f}}"
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return f.format(est)
    return f"{f.format(est)} [{f.format(lo)}, {f.format(hi)}]"
