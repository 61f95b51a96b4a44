"""The figure of ``renderlab crosscheck``: per frame, Mitsuba, Cycles, the relative radiance difference, the
hit-point gap and the shadow-edge shift, each difference on a colour scale fitted to its data, with the issue's
target in the title (PASS / FAIL) and marked on the colour bar where it falls inside the scale.

A panel with nothing to show (a frame without a cast-shadow edge, or without a common hit) is left out with a
one-line note in its place; :func:`figure` returns those notes. Saved as PNG (150 dpi) and SVG, like the
reports (this module sits below :mod:`renderlab.report` in the layers, so it does not import its style).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["figure"]

RADIANCE = "L (W m⁻² sr⁻¹)"
STANDOUT = "#D55E00"  # Okabe–Ito vermillion


def _verdict(value: float, target: float) -> str:
    return "PASS" if np.isfinite(value) and value <= target else "FAIL"


def _colorbar(fig, ax, handle, label: str, target: float | None, vmax: float) -> None:
    """Colour bar with ``label``; the target drawn on it when inside the scale, named in the label when above."""
    cb = fig.colorbar(handle, ax=ax, shrink=0.85)
    if target is not None and target <= vmax:
        cb.ax.axhline(target, color="w", lw=2.0)
        cb.ax.axhline(target, color="k", lw=1.0, ls="--")
        label += "; dashed: target"
    elif target is not None:
        label += f"; target = {target / vmax:.2g} × max"
    cb.set_label(label, fontsize=7)
    cb.ax.tick_params(labelsize=7)


def _blank(ax, text: str) -> None:
    ax.set_axis_off()
    ax.text(0.5, 0.5, text, ha="center", va="center", wrap=True, fontsize=8, transform=ax.transAxes)


def _image(fig, ax, data, cmap, lo, hi, title, label, target=None):
    h = ax.imshow(data, cmap=cmap, vmin=lo, vmax=hi, interpolation="nearest")
    ax.set_title(title, fontsize=8)
    _colorbar(fig, ax, h, label, target, hi)


def _rel_panel(fig, ax, im, r, targets) -> None:
    rel = im["rel"] * 100
    finite = np.abs(rel[np.isfinite(rel)])
    span = float(np.percentile(finite, 99)) if finite.size else 0.0
    span = span if span > 0 else 1e-3
    t = 100 * targets["rad_median_rel"]
    _image(fig, ax, rel, "coolwarm", -span, span, f"(C − M)/M, scale ±p99 of |·|\nmedian |·| "
           f"{r.rad_median_rel * 100:.4f} % (target ≤ {t:g} %): {_verdict(r.rad_median_rel * 100, t)}", "%", None)


def _gap_panel(fig, ax, im, r, targets, notes) -> None:
    gap = im["gap"]
    if not np.isfinite(gap).any():
        notes.append(f"frame {r.frame}: no pixel where both renderers hit the same body: hit-point gap left out")
        _blank(ax, "hit-point gap: no common hit pixel")
        return
    t = targets["geo_max_px"]
    vmax = float(np.nanmax(gap)) or 1e-6
    _image(fig, ax, gap, "magma", 0.0, vmax, f"hit-point gap across the line of sight, scale 0–max\nmax "
           f"{r.geo_max_px:.4f} px (target ≤ {t:g} px): {_verdict(r.geo_max_px, t)}", "px", t)


def _shift_panel(fig, ax, im, r, targets, notes) -> None:
    shift = im["shift"]
    line, s = np.nonzero(np.isfinite(shift))
    if not len(line):
        notes.append(f"frame {r.frame}: no cast-shadow edge, so no shadow-edge shift: panel left out")
        _blank(ax, "shadow-edge shift: no cast-shadow\nedge in this frame")
        return
    t = targets["shadow_p99_px"]
    v = shift[line, s]
    vmax = float(np.max(v)) or 1e-6
    ax.imshow(im["Lm"], cmap="gray", vmin=0, vmax=np.percentile(im["Lm"], 99.9) or 1.0, alpha=0.35,
              interpolation="nearest")
    h = ax.imshow(np.ma.masked_invalid(shift), cmap="viridis", vmin=0.0, vmax=vmax, interpolation="nearest")
    if len(v) < 30:  # a handful of edge pixels: circled, so they can be found
        ax.scatter(s, line, s=90, facecolors="none", edgecolors=STANDOUT, linewidths=0.6, rasterized=True)
    ax.set_title(f"shadow-edge shift at {len(v)} edge px, scale 0–max\np99 {r.shadow_p99_px:.3f} px "
                 f"(target ≤ {t:g} px): {_verdict(r.shadow_p99_px, t)}", fontsize=8)
    _colorbar(fig, ax, h, "px", t, vmax)


def figure(rows, images: list[dict], path: Path, targets: dict, max_frames: int = 6) -> list[str]:
    """Draw the difference images of up to ``max_frames`` frames (evenly spaced).

    Parameters
    ----------
    rows : list of FrameAgreement
        Per-frame agreement (:mod:`renderlab.crosscheck`).
    images : list of dict
        Per-frame images of :func:`renderlab.crosscheck.frame_agreement` (``Lm, Lc, rel, gap, shift``).
    path : Path
        ``<stem>.png``; ``<stem>.svg`` is written beside it.
    targets : dict
        ``rad_median_rel``, ``geo_max_px``, ``shadow_p99_px`` (:data:`renderlab.crosscheck.TARGETS`).
    max_frames : int
        Frames drawn at most.

    Returns
    -------
    list of str
        One note per panel left out.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    pick = np.unique(np.linspace(0, len(rows) - 1, min(max_frames, len(rows))).round().astype(int))
    fig, axes = plt.subplots(len(pick), 5, figsize=(18, 3.3 * len(pick)), squeeze=False, constrained_layout=True)
    notes: list[str] = []
    for ax_row, k in zip(axes, pick):
        im, r = images[k], rows[k]
        for ax in ax_row:
            ax.set_xticks([])
            ax.set_yticks([])
        vmax = float(np.percentile(im["Lm"], 99.9)) or 1.0
        _image(fig, ax_row[0], im["Lm"], "gray", 0, vmax, f"frame {r.frame} (t = {r.time_s:g} s)\nMitsuba", RADIANCE)
        _image(fig, ax_row[1], im["Lc"], "gray", 0, vmax, f"frame {r.frame}\nCycles", RADIANCE)
        _rel_panel(fig, ax_row[2], im, r, targets)
        _gap_panel(fig, ax_row[3], im, r, targets, notes)
        _shift_panel(fig, ax_row[4], im, r, targets, notes)
    fig.suptitle("Mitsuba vs Cycles: each difference on a colour scale fitted to its data; targets: median "
                 f"radiometric ≤ {100 * targets['rad_median_rel']:g} %, hit-point gap ≤ {targets['geo_max_px']:g} px, "
                 f"shadow-edge p99 ≤ {targets['shadow_p99_px']:g} px", fontsize=10)
    stem = Path(path).with_suffix("")
    fig.savefig(stem.with_suffix(".png"), dpi=150)
    fig.savefig(stem.with_suffix(".svg"), metadata={"Date": None})
    plt.close(fig)
    return notes
