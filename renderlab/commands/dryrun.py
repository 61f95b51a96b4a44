"""``--dry-run`` of ``renderlab render`` and ``renderlab campaign``: what would be made and what it would cost.

The request is checked as the real run checks it (scenario, ``--set``, the campaign plan), then described:
frames, image size, samples per pixel, rays (pixels × spp × frames × runs), the EV5 body's global facets
(``world.facet_m``) and site cells (``world.site.cell_m``), the disk per frame and in all, the memory of one run,
and whether the request is within the cost limits. The numbers come from the cost model
(:func:`renderlab.commands.cost.estimate`, upper-side estimates). Nothing is created: no output folder, no staging
folder, no cache.
"""

from __future__ import annotations

from pathlib import Path

from renderlab.commands import cost
from renderlab.commands.cost import _size as size
from renderlab.errors import UserError

#: radiance channels of a frame's EXR beside the AOVs (renderlab.files.truthset.AOV_CHANNELS)
_RADIANCE = {"mono": ("Y",), "rgb": ("R", "G", "B")}


def _size(n: float) -> str:
    return size(n)


def _line(label: str, text) -> str:
    return f"  {label:<15} {text}"


def exr_channels(scenario, renderer: str | None = None) -> int:
    """Float channels of one frame's EXR: the radiance (``Y`` or ``R G B``) and the AOVs (position, normal,
    range, id)."""
    from renderlab.files.truthset import AOV_CHANNELS

    rgb = (renderer or scenario.render.renderer) == "mitsuba" and scenario.render.variant.endswith("_rgb")
    return len(_RADIANCE["rgb" if rgb else "mono"]) + len(AOV_CHANNELS)


def describe(scenario, est, *, renderer: str | None = None, runs: int = 1) -> list[str]:
    """The lines common to both commands: frames, image, samples, rays, facets, disk, memory."""
    cam, render, world = scenario.camera, scenario.render, scenario.world
    renderer = renderer or render.renderer
    spp = est.spp
    lines = [_line("frames", f"{est.frames}" + (f" per run × {runs} runs" if runs > 1 else "")),
             _line("image", f"{cam.width} × {cam.height} px = {est.pixels:.3g} px, camera {cam.model}"),
             _line("samples", f"{spp} spp (render.pixel_filter {render.pixel_filter})"),
             _line("rays", f"{est.pixels:.3g} px × {spp} spp × {est.frames} frames"
                           + (f" × {runs} runs" if runs > 1 else "") + f" = {est.samples:.3g}"),
             _line("renderer", renderer + (f", variant {render.variant}" if renderer == "mitsuba" else ""))]
    if world.kind == "ev5":
        shape = f"shape file {world.shape_file}" if world.shape_file else f"world.facet_m {world.facet_m:g} m"
        lines.append(_line("EV5 facets", f"{est.facets:.3g} global ({shape}), {est.site_cells:.3g} site cells "
                                         f"(world.site.cell_m {world.site.cell_m:g} m over "
                                         f"{world.site.extent_m:g} m)"))
    frames_total = max(1, est.frames * runs)
    channels = exr_channels(scenario, renderer)
    lines.append(_line("disk", f"~{_size(est.disk_bytes / frames_total)} per frame (EXR: {channels} float "
                               f"channels × {est.pixels:.3g} px × 4 B = {_size(channels * est.pixels * 4)}; DN PNG, "
                               f"preview), ~{_size(est.disk_bytes)} in all"))
    lines.append(_line("memory", f"~{_size(est.memory_bytes)} per run"))
    return lines


def _limits(est, out, allow_large: bool) -> str:
    try:
        cost.check(est, out=Path(out) if out else None, allow_large=allow_large, what="the request")
    except UserError as err:
        return f"over: {str(err).removeprefix('the request is too large: ').split(' (estimate:')[0]}; " \
               "the real run is refused without --allow-large"
    return "within the limits (renderlab.commands.cost.LIMITS)" + (" (--allow-large)" if allow_large else "")


def render_dry_run(scenario, args) -> int:
    """Print what ``renderlab render`` would make (``args``: its parsed arguments); nothing is created."""
    from renderlab.files.truthset import TruthSetWriter

    out = Path(args.out)
    TruthSetWriter(out, {}, overwrite=args.overwrite)  # the target checks of the real run; creates nothing
    est = cost.estimate(scenario, frames=args.frames)
    state = "exists; --overwrite would replace it" if out.exists() else "would be created"
    print(f"renderlab: dry run of render {args.scenario}: nothing is created")
    print(_line("scenario", f"{scenario.name}: world {scenario.world.kind}, trajectory {scenario.trajectory.kind}"))
    print(_line("out", f"{out} ({state})"))
    for line in describe(scenario, est, renderer=args.renderer):
        print(line)
    print(_line("seed", args.seed if args.seed is not None else scenario.render.seed))
    print(_line("cost limits", _limits(est, out, args.allow_large)))
    return 0


def _finished_before(out: Path, plan, resume: bool) -> int:
    """Runs already finished in ``out``; the refusals of :func:`renderlab.campaign.store.open_campaign` (which
    creates the folder) without creating anything."""
    from renderlab.campaign import store

    if out.exists() and not out.is_dir():
        raise UserError(f"--out {out} exists and is not a directory")
    if (out / store.MANIFEST).is_file():
        if not resume:
            raise UserError(f"--out {out} already holds a campaign; pass --resume to continue it or choose a new "
                            "--out")
        if store.read_manifest(out).get("plan") != plan.plan_dict():
            raise UserError(f"--resume: {out} was made with a different plan; use a new --out")
        return len(store.finished_runs(out, plan.runs))
    if out.is_dir() and any(out.iterdir()):
        raise UserError(f"--out {out} exists, is not empty and holds no campaign")
    return 0


def campaign_dry_run(scenario, plan, args) -> int:
    """Print what ``renderlab campaign`` would run (``plan``: the validated plan); nothing is created."""

    out = Path(args.out)
    done = _finished_before(out, plan, args.resume)
    todo = plan.runs - done
    est = cost.estimate(scenario, runs=max(1, todo))
    print(f"renderlab: dry run of campaign {args.scenario}: nothing is created")
    print(_line("scenario", f"{scenario.name}: world {scenario.world.kind}, trajectory {scenario.trajectory.kind}"))
    print(_line("study", plan.study))
    print(_line("runs", f"{plan.runs}" + (f" ({done} already finished in {out}, {todo} to run)" if done else "")
                + f", root seed {plan.seed}"))
    print(_line("out", f"{out} ({'resumed' if args.resume and done else 'would be created'})"))
    print(_line("workers", "in this process" if args.workers == 0 else
                f"Dask scheduler {args.scheduler}" if args.scheduler else
                f"{args.workers} local Dask workers" if args.workers else "local Dask workers, one per core"))
    for line in describe(scenario, est, runs=max(1, todo)):
        print(line)
    print(_line("cost limits", _limits(est, out, args.allow_large)))
    print("  (per-run renders are an upper bound: runs whose truth is cached or that render nothing cost less)")
    return 0
