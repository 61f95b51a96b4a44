"""The tables, page and figure of ``renderlab crosscheck``, and their regeneration by ``renderlab report FOLDER``.

A crosscheck folder holds two raw tables: ``crosscheck.parquet`` (one row per frame, the fields of
:class:`renderlab.crosscheck.FrameAgreement`; the page title in its schema metadata) and
``crosscheck_images.parquet`` (for the frames the figure draws: both renderers' radiance, the hit-point gap and
the shadow-edge shift images, float32, row-major). :func:`write_report` makes ``crosscheck.md`` and
``crosscheck.png`` (and ``.svg`` under ``renderlab report --svg``) from these two tables alone, so the run and
``renderlab report FOLDER`` give the same files.

The page: the targets (:data:`~renderlab.crosscheck.agreement.TARGETS`) with the worst frame and PASS / FAIL, then one row per frame with its verdict.
The figure: per frame, Mitsuba, Cycles, the relative radiance difference, the hit-point gap and the shadow-edge
shift, each difference on a colour scale fitted to its data, with the target in the title (PASS / FAIL) and
marked on the colour bar where it falls inside the scale. A panel with nothing to show (a frame without a
cast-shadow edge, or without a common hit) is left out with a one-line note in its place; :func:`figure` returns
those notes. Saved by the lab's one figure writer (:func:`renderlab.contracts.result_folder.save_figure`, like the
reports; this module sits below :mod:`renderlab.report` in the layers, so it does not import its style).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from renderlab.contracts.result_folder import figures_wanted, save_figure
from renderlab.crosscheck.agreement import TARGETS, FrameAgreement, radiometric_agreement
from renderlab.errors import UserError
from renderlab.files.parquet_compact import write_compact

__all__ = ["figure", "markdown_table", "write_images", "read_images", "is_crosscheck_folder", "write_report"]

TABLE = "crosscheck.parquet"
IMAGES = "crosscheck_images.parquet"
TITLE_KEY = b"renderlab.crosscheck.title"
#: image name in the figure's dict → column of the images table (float32, row-major)
IMAGE_COLUMNS = {"Lm": "radiance_mitsuba_w_m2_sr", "Lc": "radiance_cycles_w_m2_sr", "gap": "gap_px",
                 "shift": "shadow_shift_px"}

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


def _pick(n: int, max_frames: int) -> np.ndarray:
    """Indices of the frames drawn: up to ``max_frames`` evenly spaced."""
    return np.unique(np.linspace(0, n - 1, min(max_frames, n)).round().astype(int))


def figure(rows, images: list[dict], path: Path, targets: dict, max_frames: int = 6) -> list[str]:
    """Draw the difference images of up to ``max_frames`` frames (evenly spaced).

    Parameters
    ----------
    rows : list of FrameAgreement
        Per-frame agreement (:mod:`renderlab.crosscheck.agreement`).
    images : list of dict
        Per-frame images of :func:`renderlab.crosscheck.agreement.frame_agreement` (``Lm, Lc, rel, gap, shift``).
    path : Path
        ``<stem>.png`` (:func:`~renderlab.contracts.result_folder.save_figure`; ``<stem>.svg`` beside it under
        ``renderlab report --svg``).
    targets : dict
        ``rad_median_rel``, ``geo_max_px``, ``shadow_p99_px`` (:data:`renderlab.crosscheck.agreement.TARGETS`).
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

    pick = _pick(len(rows), max_frames)
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
    save_figure(fig, Path(path).with_suffix(""))
    return notes


def _checks(targets: dict) -> list[tuple[str, str, str, float, str]]:
    """(row field, what, target key, scale, unit) of each banded quantity of the page."""
    return [("rad_median_rel", "radiometric difference, median of abs(L_C / L_M − 1) over lit pixels", "rad_median_rel",
             100.0, "%"),
            ("geo_max_px", "hit-point gap across the line of sight, max", "geo_max_px", 1.0, "px"),
            ("lmk_max_px", "hit-point gap at the landmark truth pixels, max", "geo_max_px", 1.0, "px"),
            ("reproj_cycles_max_px", "Cycles hit point re-projected through the lab's camera, max", "geo_max_px", 1.0,
             "px"),
            ("shadow_p99_px", "shadow-edge shift Cycles vs Mitsuba, p99", "shadow_p99_px", 1.0, "px"),
            ("edge_vs_oracle_mitsuba_p99_px", "Mitsuba's shadow edges vs the referee, p99", "shadow_p99_px", 1.0, "px"),
            ("edge_vs_oracle_cycles_p99_px", "Cycles' shadow edges vs the referee, p99", "shadow_p99_px", 1.0, "px")]


def _verdict_md(value: float, target: float) -> str:
    return "n/a (no pixels)" if not np.isfinite(value) else f"**{_verdict(value, target)}**"


def markdown_table(rows, title: str, targets: dict) -> str:
    """The page: the targets with the worst frame and PASS / FAIL (n/a where a check has no pixels), then one row
    per frame (its verdict: PASS when every applicable target is met)."""
    f = lambda v, fmt: "–" if not np.isfinite(v) else format(v, fmt)  # noqa: E731
    lines = [f"# {title}", "", f"{len(rows)} frames. Targets on the worst frame:", "",
             "| quantity | target | worst frame | worst value | verdict |", "|---|---|---|---|---|"]
    passed = {r.frame: True for r in rows}
    for field, what, key, scale, unit in _checks(targets):
        vals = np.array([getattr(r, field) for r in rows], float)
        t = targets[key]
        for r, v in zip(rows, vals):
            passed[r.frame] &= not np.isfinite(v) or v <= t
        k = int(np.nanargmax(vals)) if np.isfinite(vals).any() else -1
        worst = "–" if k < 0 else str(rows[k].frame)
        lines.append(f"| {what} | ≤ {t * scale:g} {unit} | {worst} | {f(vals[k] * scale if k >= 0 else np.nan, '.4f')} "
                     f"{unit} | {_verdict_md(vals[k] if k >= 0 else np.nan, t)} |")
    head = ["frame", "lit px", "lit in one only", "rad. median", "rad. p99", "geo median px", "geo max px",
            "Δrange/range median / max", "reproj M/C max px", "landmarks", "lmk max px", "shadow-edge px",
            "shadow median px", "shadow p99 px", "oracle: M off / C off / both ok", "edge vs oracle p99 M / C px",
            "verdict"]
    lines += ["", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        lines.append("| " + " | ".join([
            str(r.frame), str(r.n_lit), str(r.n_lit_one_only), f(r.rad_median_rel * 100, ".4f") + " %",
            f(r.rad_p99_rel * 100, ".2f") + " %", f(r.geo_median_px, ".5f"), f(r.geo_max_px, ".4f"),
            f(r.range_rel_median, ".1e") + " / " + f(r.range_rel_max, ".1e"),
            f(r.reproj_mitsuba_max_px, ".4f") + " / " + f(r.reproj_cycles_max_px, ".4f"),
            str(r.n_landmarks), f(r.lmk_max_px, ".4f"), str(r.n_shadow_edge),
            f(r.shadow_median_px, ".3f"), f(r.shadow_p99_px, ".3f"),
            "–" if r.oracle_mitsuba_off < 0 else f"{r.oracle_mitsuba_off} / {r.oracle_cycles_off} / {r.oracle_both_ok}",
            f(r.edge_vs_oracle_mitsuba_p99_px, ".3f") + " / " + f(r.edge_vs_oracle_cycles_p99_px, ".3f"),
            "**PASS**" if passed[r.frame] else "**FAIL**"]) + " |")
    return "\n".join(lines) + "\n"


def write_images(rows, images: list[dict], out_dir: Path, max_frames: int = 6) -> Path:
    """``crosscheck_images.parquet``: the images of the frames :func:`figure` draws (float32, the lab's compact
    writer); the frames' times are in the agreement table."""
    import pyarrow as pa

    pick = _pick(len(rows), max_frames)
    cols: dict[str, list] = {"frame": [], "height": [], "width": [], **{c: [] for c in IMAGE_COLUMNS.values()}}
    for k in pick:
        H, W = images[k]["Lm"].shape
        cols["frame"].append(int(rows[k].frame))
        cols["height"].append(H)
        cols["width"].append(W)
        for name, col in IMAGE_COLUMNS.items():
            cols[col].append(np.asarray(images[k][name], np.float32).ravel())
    table = pa.table({k: (pa.array(v, pa.list_(pa.float32())) if k in IMAGE_COLUMNS.values() else v)
                      for k, v in cols.items()})
    path = Path(out_dir) / IMAGES
    write_compact(table, path)
    return path


def read_images(path: Path) -> tuple[list[int], list[dict]]:
    """(frames, images) of :func:`write_images`; the relative radiance difference is recomputed from the two
    radiance images over the lit pixels (:func:`renderlab.crosscheck.agreement.radiometric_agreement`)."""
    import pyarrow.parquet as pq

    t = pq.read_table(str(path)).to_pydict()
    frames, images = [], []
    for i, frame in enumerate(t["frame"]):
        shape = (int(t["height"][i]), int(t["width"][i]))
        im = {name: np.asarray(t[col][i], np.float32).astype(np.float64).reshape(shape)
              for name, col in IMAGE_COLUMNS.items()}
        lit, _ = radiometric_agreement(im["Lm"], im["Lc"])
        im["rel"] = np.full(shape, np.nan)
        im["rel"][lit] = im["Lc"][lit] / im["Lm"][lit] - 1.0
        frames.append(int(frame))
        images.append(im)
    return frames, images


def is_crosscheck_folder(folder: Path) -> bool:
    """A folder written by ``renderlab crosscheck`` (it holds ``crosscheck.parquet``)."""
    return (Path(folder) / TABLE).is_file()


def _load(folder: Path):
    """(title, rows, frames, images) of a crosscheck folder; UserError for a missing or unreadable table."""
    import pyarrow.parquet as pq


    folder = Path(folder)
    if not (folder / IMAGES).is_file():
        raise UserError(f"{folder}: no {IMAGES} beside {TABLE} (re-run renderlab crosscheck to write it)")
    try:
        t = pq.read_table(str(folder / TABLE))
        fields = set(FrameAgreement.__dataclass_fields__)
        if not fields <= set(t.column_names):
            raise ValueError(f"missing columns {', '.join(sorted(fields - set(t.column_names)))}")
        rows = [FrameAgreement(**{k: v for k, v in r.items() if k in fields}) for r in t.to_pylist()]
        frames, images = read_images(folder / IMAGES)
    except (OSError, ValueError, KeyError) as exc:
        raise UserError(f"cannot read the crosscheck tables of {folder}: {' '.join(str(exc).split())[:200]}") from None
    title = (t.schema.metadata or {}).get(TITLE_KEY, f"Mitsuba vs Cycles: {folder.name}".encode()).decode()
    by_frame = {r.frame: r for r in rows}
    if not set(frames) <= set(by_frame):
        raise UserError(f"{folder / IMAGES}: frames {sorted(set(frames) - set(by_frame))} are not in {TABLE}")
    return title, rows, [by_frame[f] for f in frames], images


def write_report(folder: Path, out_dir: Path) -> list[Path]:
    """``crosscheck.md`` and ``crosscheck.png`` (``.svg`` under ``--svg``) of ``folder`` into ``out_dir``, from its two
    tables alone (the page only under :func:`~renderlab.contracts.result_folder.tables_only`); every file is written
    under a hidden name first and renamed into place when all are done."""
    import os
    import shutil
    import tempfile


    title, rows, drawn, images = _load(folder)
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise UserError(f"--out {out_dir} exists and is not a folder")
    out_dir.mkdir(parents=True, exist_ok=True)
    stage = Path(tempfile.mkdtemp(prefix=".crosscheck-report-", dir=out_dir))
    try:
        (stage / "crosscheck.md").write_text(markdown_table(rows, title, TARGETS), encoding="utf-8")
        names = ["crosscheck.md"]
        if figures_wanted():  # not under renderlab report --tables-only
            figure(drawn, images, stage / "crosscheck.png", TARGETS, max_frames=len(drawn))
            names += sorted(p.name for p in stage.glob("crosscheck.*") if p.suffix in (".png", ".svg"))
        done = []
        for name in names:
            os.replace(stage / name, out_dir / name)
            done.append(out_dir / name)
        return done
    finally:
        shutil.rmtree(stage, ignore_errors=True)


class _CrosscheckFolder:
    """The ``renderlab crosscheck`` folder as a result-folder kind (:mod:`renderlab.contracts.result_folder`)."""

    name = "crosscheck"

    def recognises(self, folder: Path) -> bool:
        return is_crosscheck_folder(folder)

    def write_report(self, folder: Path, out_dir: Path | None) -> list[Path]:
        return write_report(folder, Path(out_dir) if out_dir is not None else Path(folder))


RESULT_FOLDER = _CrosscheckFolder()
