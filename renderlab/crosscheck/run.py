"""``renderlab crosscheck``: render a scenario with both renderers, compare the truth sets frame by frame
(:mod:`renderlab.crosscheck.agreement`), referee the pixels lit in one renderer only with the float64 ray oracle,
write the two tables and, from them alone, the page and figure (:mod:`renderlab.crosscheck.figures`)."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from renderlab.crosscheck.agreement import TARGETS, FrameAgreement, frame_agreement
from renderlab.crosscheck.figures import TABLE, TITLE_KEY, write_images, write_report
from renderlab.crosscheck.figures import figure as draw
from renderlab.crosscheck.figures import markdown_table as table
from renderlab.errors import UserError
from renderlab.extras import require
from renderlab.files.parquet_compact import write_compact
from renderlab.files.truthset import TruthSet
from renderlab.pipeline import render_truthset
from renderlab.render.ray_oracle import consistent, oracle_scene, pixel_truth
from renderlab.worlds.base import make_plan

ORACLE_K = 16  # oracle sub-samples per pixel side
ORACLE_MAX_PX = 300  # refereed pixels per frame and kind (evenly spaced in raster order beyond this)


def _spread(mask: np.ndarray, n_max: int) -> tuple[np.ndarray, np.ndarray]:
    line, s = np.nonzero(mask)
    if len(line) > n_max:
        keep = np.linspace(0, len(line) - 1, n_max).round().astype(int)
        line, s = line[keep], s[keep]
    return line, s


def referee(row: FrameAgreement, images: dict, oracle, spec, spp: int) -> None:
    """Fill the ``oracle_*`` and ``edge_vs_oracle_*`` fields of ``row`` (see the module docstring)."""
    Lm, Lc = images["Lm"], images["Lc"]
    line, s = _spread(images["one_only"], ORACLE_MAX_PX)
    row.n_oracle = int(len(line))
    if len(line):
        sl = np.column_stack([s, line]).astype(float)
        truth = pixel_truth(oracle, spec, sl, k=ORACLE_K)
        ok_m, ok_c = consistent(Lm[line, s], truth, spp, ORACLE_K), consistent(Lc[line, s], truth, spp, ORACLE_K)
        redo = ~(ok_m & ok_c)  # a verdict against a renderer is confirmed with 4x finer sub-samples
        if redo.any():
            fine = pixel_truth(oracle, spec, sl[redo], k=4 * ORACLE_K)
            ok_m[redo] = consistent(Lm[line, s][redo], fine, spp, 4 * ORACLE_K)
            ok_c[redo] = consistent(Lc[line, s][redo], fine, spp, 4 * ORACLE_K)
        row.oracle_mitsuba_off, row.oracle_cycles_off = int((~ok_m).sum()), int((~ok_c).sum())
        row.oracle_both_ok = int((ok_m & ok_c).sum())
    else:
        row.oracle_mitsuba_off = row.oracle_cycles_off = row.oracle_both_ok = 0
    line, s = _spread(images["edge"], ORACLE_MAX_PX // 3)
    if len(line):
        # the shadow-edge metric of shadow_edge_shift_px with the oracle as the second image: the
        # difference summed over the pixel and its two neighbours along the dominant gradient axis
        gy, gx = np.gradient(Lm)
        along_x = np.abs(gx[line, s]) >= np.abs(gy[line, s])
        k = np.array([-1, 0, 1])
        nl = (line[:, None] + np.where(along_x[:, None], 0, k[None, :])).ravel()
        ns = (s[:, None] + np.where(along_x[:, None], k[None, :], 0)).ravel()
        px, inv = np.unique(np.column_stack([ns, nl]), axis=0, return_inverse=True)
        truth = pixel_truth(oracle, spec, px.astype(float), k=ORACLE_K)
        L_or = truth.radiance[inv.ravel()].reshape(-1, 3)
        step = images["step"][line, s]
        for name, L in (("mitsuba", Lm), ("cycles", Lc)):
            moved = np.abs((L[nl, ns].reshape(-1, 3) - L_or).sum(axis=1)) / step
            setattr(row, f"edge_vs_oracle_{name}_p99_px", float(np.percentile(moved, 99)))


def compare_truthsets(path_m: Path, path_c: Path) -> tuple[list[FrameAgreement], list[dict]]:
    """Per-frame agreement rows and images of two truth sets of the same scenario."""
    tm, tc = TruthSet.open(path_m), TruthSet.open(path_c)
    if len(tm) != len(tc):
        raise UserError(f"truth sets differ in frame count: {len(tm)} vs {len(tc)}")
    lmk_table = None
    if (tm.path / "landmark_truth.parquet").is_file():
        lmk_table = {k: np.asarray(v) for k, v in tm.read_table("landmark_truth").to_pydict().items()}
    rows, images = [], []
    for i in range(len(tm)):
        fm, fc = tm.load(i), tc.load(i)
        lm = None
        if lmk_table is not None:
            sel = (lmk_table["frame"] == fm.index) & lmk_table["visible"].astype(bool)
            lm = {"s": lmk_table["s"][sel].astype(float), "l": lmk_table["l"][sel].astype(float)}
        row, imgs = frame_agreement(fm, fc, lm)
        rows.append(row)
        images.append(imgs)
    return rows, images


def markdown_table(rows: list[FrameAgreement], title: str) -> str:
    """The Markdown page of the agreement rows: the targets with PASS/FAIL, then one row per frame
    (:func:`renderlab.crosscheck.figures.markdown_table`)."""
    return table(rows, title, TARGETS)


def figure(rows: list[FrameAgreement], images: list[dict], path: Path, max_frames: int = 6) -> list[str]:
    """Difference images (:func:`renderlab.crosscheck.figures.figure`, PNG + SVG); returns the notes of panels left
    out (a frame without a cast-shadow edge has no shadow-edge panel)."""
    return draw(rows, images, path, TARGETS, max_frames=max_frames)


def _referee_all(scenario, base_dir, rows, images) -> None:
    plan = make_plan(scenario, base_dir)
    specs = {spec.index: spec for spec in plan.frames}
    cache: dict = {}
    for row, imgs in zip(rows, images):
        spec = specs[row.frame]
        key = plan.scene_key(spec)
        if key not in cache:  # the exact geometry: tiled surfaces (EV5 levels of detail) at full resolution
            cache[key] = oracle_scene(plan.scene(key).untiled())
        if cache[key] is not None:
            referee(row, imgs, cache[key], spec, scenario.render.spp)


def run_crosscheck(scenario, base_dir: Path, out_dir: Path, *, frames: int | None = None,
                   keep_truthsets: bool = False, progress: bool = True) -> list[FrameAgreement]:
    """Render ``scenario`` with both renderers and write ``crosscheck.parquet`` (one row per frame),
    ``crosscheck_images.parquet`` (the drawn frames' images), and from those two tables alone ``crosscheck.md`` and
    ``crosscheck.png`` / ``.svg`` into ``out_dir`` (truth sets in ``out_dir/truthsets/`` if ``keep_truthsets``);
    ``renderlab report out_dir`` remakes the last two (:func:`renderlab.crosscheck.figures.write_report`)."""
    import pyarrow as pa


    require("bpy", "cycles", load=False)  # before out_dir is made
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise UserError(f"--out {out_dir} exists and is not a folder")
    out_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="renderlab-crosscheck-") as tmp:
        root = out_dir / "truthsets" if keep_truthsets else Path(tmp)
        paths = {}
        for renderer in ("mitsuba", "cycles"):
            paths[renderer] = render_truthset(scenario, base_dir, root / renderer, frames=frames,
                                              renderer=renderer, progress=progress, overwrite=True)
        rows, images = compare_truthsets(paths["mitsuba"], paths["cycles"])
    if scenario.render.pixel_filter == "box":  # the oracle gives box-filtered pixels
        _referee_all(scenario, base_dir, rows, images)
    cols = list(FrameAgreement.__dataclass_fields__)
    table = pa.table({c: [getattr(r, c) for r in rows] for c in cols})
    table = table.replace_schema_metadata({TITLE_KEY: f"Mitsuba vs Cycles: {scenario.name}"})
    write_compact(table, out_dir / TABLE)
    write_images(rows, images, out_dir)
    write_report(out_dir, out_dir)  # crosscheck.md and the figure from the two tables just written
    return rows
