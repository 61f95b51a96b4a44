"""Scenario → truth set: world, camera path, renderer, sensor, files; and the warm frame API
(:mod:`renderlab.pipeline.frame_api`: :class:`~renderlab.pipeline.frame_api.Renderer`, in memory), which renders
every frame of every truth set.

Seeds: the scenario's ``render.seed`` (or ``--seed``) roots a ``SeedSequence``; frame k uses its
k-th spawned child, split again into the renderer's sample pattern and the sensor noise. The same
seed therefore gives bit-identical EXR and DN files, and any frame can be re-rendered alone.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from renderlab.errors import UserError
from renderlab.files.truthset import TruthSetWriter
from renderlab.pipeline.backend import make_backend  # noqa: F401  (re-exported)
from renderlab.scenario import Scenario
from renderlab.worlds.base import frame_specs  # noqa: F401  (re-exported)


def render_truthset(
    scenario: Scenario,
    base_dir: Path,
    out_dir: Path,
    *,
    frames: int | None = None,
    seed: int | None = None,
    renderer: str | None = None,
    progress: bool = True,
    overwrite: bool = False,
) -> Path:
    """Render a scenario into a truth set folder (written atomically) and return its path.

    The world's :class:`renderlab.worlds.base.WorldPlan` supplies the frames, the scene(s), per-frame
    metadata and truth-table rows; :class:`renderlab.pipeline.frame_api.Renderer` renders them (seeds, renderer,
    sensor) and this function writes the files.
    """
    from renderlab.pipeline.frame_api import Renderer

    seed = scenario.render.seed if seed is None else int(seed)
    if seed < 0:
        raise UserError(f"--seed must be a non-negative integer, got {seed}")
    if seed != scenario.render.seed:  # the manifest's scenario records the seed actually used
        scenario = scenario.model_copy(update={"render": scenario.render.model_copy(update={"seed": seed})})
    renderer = renderer or scenario.render.renderer
    if frames is not None and frames < 1:
        raise UserError(f"--frames must be at least 1, got {frames}")
    head = {"scenario": scenario.to_dict(), "seed": seed}
    TruthSetWriter(out_dir, head, overwrite=overwrite)  # refuses a bad output folder before the slow start
    r = Renderer(scenario, base_dir, renderer=renderer)
    specs = r.plan.frames if frames is None else r.plan.frames[:frames]
    head["render_frame"] = r.plan.render_frame
    seeds = [r.seed_for(spec.index) for spec in specs]
    return write_frames(out_dir, r, specs, seeds, head=head, overwrite=overwrite, progress=progress)


def write_frames(out_dir: Path, renderer, specs: list, seeds: list, *, head: dict,
                 overwrite: bool = False, progress: bool = False, background: bool = True) -> Path:
    """The truth-set loop shared by :func:`render_truthset` and the per-pose truth cache
    (:func:`renderlab.campaign.cache.render_frames`): each frame spec and its ``SeedSequence`` through
    :meth:`Renderer.render_spec <renderlab.pipeline.frame_api.Renderer.render_spec>` (auto-exposure on the set's first frame, or per frame), and
    the frame, the plan's metadata and truth tables and a contact sheet written into a truth set at ``out_dir``
    (staged: all or nothing); a warning names the frames with more than 1 % saturated pixels. ``head`` is the
    manifest's head. ``background``: frame k's files are written in a thread while frame k+1 renders (the same
    bytes, :mod:`renderlab.files.background`)."""
    from tqdm import tqdm

    plan = renderer.plan
    renderer.reset_exposure()  # auto_exposure = true: this set's first frame chooses it
    writer, rows, saturated = None, {}, []
    try:
        for spec, child in tqdm(list(zip(specs, seeds)), desc="render", unit="frame", disable=not progress):
            frame = renderer.render_spec(spec, child)
            if writer is None:
                backend = renderer.backend
                info = {"name": backend.name, "version": backend.version, "variant": backend.variant}
                writer = TruthSetWriter(out_dir, {**head, "renderer": info}, overwrite=overwrite, background=background,
                                        exr_compression=renderer.scenario.render.exr_compression).__enter__()
                plan.write_static(writer)
            writer.add_frame(spec.index, float(spec.pose.time_s), frame.aovs.exr_channels(), frame.dn,
                             frame.meta, dn_bits=renderer.options.bits)
            for name, new_rows in frame.truth.items():
                rows.setdefault(name, []).extend(new_rows)
            if frame.saturated_px > 0.01 * frame.dn.size:
                saturated.append((spec.index, frame.saturated_px / frame.dn.size))
        for name, table_rows in rows.items():
            writer.add_table(name, _rows_to_table(table_rows))
        writer.add_file("contact_sheet.png", _contact_sheet_png(writer))
    except BaseException as exc:
        if writer is not None:
            writer.__exit__(type(exc), exc, exc.__traceback__)
        raise
    writer.__exit__(None, None, None)
    if saturated:
        import sys

        worst = max(saturated, key=lambda x: x[1])
        print(f"renderlab: warning: {len(saturated)} frame(s) have more than 1 % saturated pixels (worst: frame "
              f"{worst[0]}, {100 * worst[1]:.1f} %); each frame's count is in the manifest (sensor.saturated_px)",
              file=sys.stderr)
    return Path(out_dir)


def _rows_to_table(rows: list[dict]):
    """A pyarrow table from row dicts (columns in first-row order)."""
    import pyarrow as pa

    cols = list(rows[0]) if rows else []
    return pa.table({c: [r[c] for r in rows] for c in cols})


def _contact_sheet_png(writer) -> bytes:
    """PNG bytes of a grid of the frames' sensor images (up to 16, evenly spaced), frame numbers on top."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from renderlab.contracts.result_folder import figure_png
    from renderlab.files.imageio import read_dn_png

    frames = writer.manifest()["frames"]
    pick = np.unique(np.linspace(0, len(frames) - 1, min(16, len(frames))).round().astype(int))
    ncol = int(np.ceil(np.sqrt(len(pick))))
    nrow = int(np.ceil(len(pick) / ncol))
    fig, axes = plt.subplots(nrow, ncol, figsize=(3 * ncol, 3 * nrow), squeeze=False, constrained_layout=True)
    for ax in axes.ravel():
        ax.axis("off")
    for ax, k in zip(axes.ravel(), pick):
        rec = frames[k]
        dn = read_dn_png(writer.staging_dir / rec["dn"])
        ax.imshow(dn, cmap="gray", vmin=0, vmax=max(1, int(dn.max())), interpolation="nearest")
        ax.set_title(f"frame {rec['index']}  t={rec['time_s']:.1f} s", fontsize=8)
    try:
        return figure_png(fig)  # the lab's one figure writer: 100-dpi palette PNG, the same bytes every run
    finally:
        plt.close(fig)
