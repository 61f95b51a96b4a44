"""The warm frame API (``renderlab.Renderer.frame``) against Mitsuba's own floor, side by side in one process.

Three measurements, one run, the load average printed before and after:

* **full EV5** (``scenes/ev5_descent.toml``: 1.30 M global facets, 64 m site at 2 cm, 20.5 M facets),
  ``--frames`` descent frames at ``--size``², ``--spp`` spp. Per frame, each right after another frame:
  ``Renderer.frame(k)`` with the default design (the full DEM marched, :mod:`renderlab.render.mitsuba_dem`: nothing
  changes per frame), and with ``tile_design = "two"`` (the frame's LOD tiles in a second scene) twice — the tile set
  changed, then the same tiles; and two floors, ``mi.render`` with Mitsuba's C++ ``direct`` integrator (one emitter
  sample, no BSDF sample, radiance only, perspective sensor) timed after a warm-up call, each of the geometry one
  design renders: the static bodies with the **full site** (``world.site.lod = false``, one loaded scene) for the
  default, with **this frame's tiles** (merged into one loaded scene) for the tiles.
  Then the frames as ``renderlab render`` makes them (:func:`renderlab.pipeline.write_frames`: the API frame + the
  EXR (``render.exr_compression``) and PNG files, written in the loop or, the default, by the writer's background
  thread while the next frame renders; ``--repeats`` interleaved passes of each; ``--file-settings new,old``: the
  writers' zlib settings as they are and as they were before, ZIP level 4 and PNG level 3 with the default strategy,
  as further interleaved passes) against ``mi.render``
  (``direct``) of a 1.31 M-triangle sphere (trimesh icosphere, 8 subdivisions) filling the frame, timed between
  the passes. ``--skip-api`` renders every frame once (warm-up) and measures only this.
* **descent-navigation world** (``results/descent_navigation/scenario.toml`` at 256², 16 spp): every frame of its
  descent through ``Renderer.frame`` in memory, twice (planned poses, then poses moved 0.3 m as a flown trajectory
  would), frames per second and the distribution of frame times.

Usage::

    .venv/bin/python benchmarks/bench_frame_api.py [--frames 4] [--size 1024] [--spp 16] [--skip-full] [--skip-descent]
        [--skip-api] [--repeats 2] [--bar-frames 2,3] [--compressions zip,none] [--file-settings new,old]
        [--writers loop,background]

The world cache is ``$RENDERLAB_CACHE`` (default ``~/.cache/renderlab``): the first run builds and stores the worlds.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))
DIRECT = {"type": "direct", "emitter_samples": 1, "bsdf_samples": 0, "hide_emitters": True}


def _sets(size: int, spp: int, frames: int) -> list[str]:
    f = 4871.6 * size / 1024
    return [f"trajectory.frames={frames}", f"camera.width={size}", f"camera.height={size}", f"camera.fx={f}",
            f"camera.fy={f}", f"camera.cx={(size - 1) / 2}", f"camera.cy={(size - 1) / 2}", f"render.spp={spp}"]


def _floor(mi, backend, spec, spp: int) -> float:
    """Seconds of a warm ``mi.render`` (``direct``) of ``backend``'s loaded scene from ``spec``'s camera."""
    import drjit as dr
    from bench_ev5_descent import _sensor

    sensor, integ = _sensor(mi, backend, spec, spp), mi.load_dict(DIRECT)
    for k in range(2):
        t0 = time.perf_counter()
        dr.eval(mi.render(backend.scene, sensor=sensor, integrator=integ, spp=spp, seed=k))
        dr.sync_thread()
        dt = time.perf_counter() - t0
    return dt


def _full_site_backend(sets: list[str]):
    """A one-scene backend of the EV5 world (``--set`` overrides ``sets``) with the site whole at full resolution
    (``world.site.lod = false``): the geometry the default DEM design renders, for its floor (Embree builds its
    21.8 M facets once, not timed)."""
    from renderlab.pipeline import make_backend
    from renderlab.pipeline.frame_api import Renderer

    rf = Renderer(REPO / "scenes" / "ev5_descent.toml", overrides=[*sets, "world.site.lod=false"])
    return make_backend(rf.scenario, rf.plan.static_scene, "mitsuba")


def full_ev5(args) -> None:
    from renderlab.pipeline.frame_api import Renderer
    from renderlab.render.mitsuba_backend import tile_design

    sets = _sets(args.size, args.spp, args.frames) + args.set
    r = Renderer(REPO / "scenes" / "ev5_descent.toml", overrides=sets)
    if args.skip_api:  # every frame once first (kernels), as the API part leaves them
        for k in range(r.n_frames):
            r.frame(k)
        return bar_vs_sphere(args, r, r.backend.mi)
    r.frame(0)  # the DEM design's pyramid, site mesh and kernels, once per process
    with tile_design("two"):  # the backend is made at the first frame
        rt = Renderer(REPO / "scenes" / "ev5_descent.toml", overrides=sets)
        rt.frame(r.n_frames - 1)
    merged = _merged_backend(r)  # the LOD floor's one-scene geometry (static bodies + the frame's tiles)
    full = _full_site_backend(sets)  # the default design's geometry (static bodies + the full site)
    mi = merged.mi
    rows = []
    for k, spec in enumerate(r.plan.frames):
        reps = []
        for _ in range(args.repeats):  # interleaved; the median of each is kept
            r.frame((k - 1) % r.n_frames)
            t0 = time.perf_counter()
            r.frame(k)
            t_dem = time.perf_counter() - t0
            rt.frame((k - 1) % r.n_frames)
            t0 = time.perf_counter()
            rt.frame(k)
            t_change = time.perf_counter() - t0
            t0 = time.perf_counter()
            rt.frame(k)
            t_same = time.perf_counter() - t0
            merged._set_sun(spec)
            floor = _floor(mi, merged, spec, args.spp)
            full._set_sun(spec)
            floor_full = _floor(mi, full, spec, args.spp)
            reps.append((t_dem, t_change, t_same, floor, floor_full))
        t_dem, t_change, t_same, floor, floor_full = np.median(np.array(reps), axis=0)
        alt = r.plan.frame_meta(spec, r.plan.static_scene)["ev5"]["altitude_m"]
        rows.append((alt, t_dem, t_change, t_same, floor, floor_full))
        print(f"  frame {k} ({alt:6.0f} m), median of {args.repeats}: default (DEM march) {t_dem:.2f} s; LOD tiles in a "
              f"second scene {t_change:.2f} s (tiles changed), {t_same:.2f} s (same tiles); mi.render direct of the "
              f"full site {floor_full:.2f} s, of the frame's tiles {floor:.2f} s; ratios: DEM / full-site floor "
              f"{t_dem / floor_full:.2f}x, DEM / tiles floor {t_dem / floor:.2f}x, tiles / tiles floor "
              f"{t_change / floor:.2f}x (changed), {t_same / floor:.2f}x (same); each run (s): "
              f"{np.round(np.array(reps), 2).tolist()}", flush=True)
    a = np.array(rows)
    print(f"full EV5 {args.size}², {args.spp} spp {' '.join(args.set)}, {len(rows)} frames, each right after another "
          "frame (frame 0 after the last):")
    for label, col, fl in (("default (DEM) / full-site floor", 1, 5), ("default (DEM) / tiles floor", 1, 4),
                           ("two scenes, tiles changed / tiles floor", 2, 4),
                           ("two scenes, same tiles / tiles floor", 3, 4)):
        rat = a[:, col] / a[:, fl]
        print(f"  {label:40s}: per frame {np.round(rat, 2).tolist()}, median {np.median(rat):.2f}x, "
              f"max {rat.max():.2f}x")
    bar_vs_sphere(args, r, mi)


def bar_vs_sphere(args, r, mi) -> None:
    """Frames as ``renderlab render`` makes them (:func:`renderlab.pipeline.write_frames`: API frame + files, the
    files in the loop or in the background thread, per EXR compression of ``--compressions``) vs mi.render of a
    1.31 M-triangle sphere; the passes interleaved, the sphere timed between them. Two ratios: to the median sphere of
    the run, and paired (each pass to the mean of the spheres timed just before and after it, so a load that changes
    during the run moves both sides alike)."""
    floors = [sphere_floor(mi, args.size, args.spp)]
    writers = [{"loop": False, "background": True}[w] for w in args.writers.split(",")]
    modes = [(c, bg, fs) for fs in args.file_settings.split(",") for c in args.compressions.split(",")
             for bg in writers]
    runs: dict = {m: [] for m in modes}
    paired: dict = {m: [] for m in modes}  # each pass over the mean of the sphere timed just before and after it
    for _rep in range(args.repeats):
        for comp, background, settings in modes:
            render = r.scenario.render.model_copy(update={"exr_compression": comp})
            r.scenario = r.scenario.model_copy(update={"render": render})
            with _file_settings(settings):
                runs[(comp, background, settings)].append(_truthset_frames(r, background, args.bar_frames))
            floors.append(sphere_floor(mi, args.size, args.spp))
            paired[(comp, background, settings)].append(np.array(runs[(comp, background, settings)][-1])
                                                        / np.mean(floors[-2:]))
    floor = float(np.median(floors))
    print(f"  mi.render direct of a 1.31 M-triangle sphere (f = {args.size / 2 / np.tan(np.radians(8.0)):.0f} px): "
          f"median {floor:.2f} s ({np.round(floors, 2).tolist()}), load average {os.getloadavg()[0]:.1f}")
    for mode in modes:
        comp, background, settings = mode
        label = (f"EXR {comp}, {settings} zlib settings, "
                 + ("files by the background thread" if background else "files written in the loop"))
        t = np.median(np.array(runs[mode]), axis=0)  # per frame, median over the repeats
        rat = (t[1:] if len(t) > 1 and not args.bar_frames else t) / floor
        print(f"  renderlab-render frame ({label}) / sphere: median {np.median(rat):.2f}x "
              f"({'frames ' + str(args.bar_frames) if args.bar_frames else 'frames 1..'}), per frame "
              f"{np.round(t / floor, 2).tolist()}, mean "
              f"{t.mean() / floor:.2f}x over all frames; frames {np.round(t, 2).tolist()} s "
              f"(each run: {[np.round(x, 2).tolist() for x in runs[mode]]})", flush=True)
        pr = np.array(paired[mode])
        pr = pr[:, 1:] if pr.shape[1] > 1 and not args.bar_frames else pr
        print(f"    paired with the spheres timed around each pass: median {np.median(pr):.2f}x, per pass "
              f"{np.round(pr.mean(axis=1), 2).tolist()} (mean over its frames)", flush=True)


@contextlib.contextmanager
def _file_settings(name: str):
    """The frame files' zlib settings: ``new`` as :mod:`renderlab.files.imageio` has them, ``old`` as they were before
    (EXR ZIP at OpenEXR's default level 4, PNG level 3 with zlib's default strategy)."""
    import cv2

    from renderlab.files import imageio

    saved = imageio.EXR_ZIP_LEVEL, imageio.PNG_PARAMS
    if name == "old":
        imageio.EXR_ZIP_LEVEL, imageio.PNG_PARAMS = 4, (cv2.IMWRITE_PNG_COMPRESSION, 3)
    elif name != "new":
        raise SystemExit(f"--file-settings: 'new' or 'old', got {name!r}")
    try:
        yield
    finally:
        imageio.EXR_ZIP_LEVEL, imageio.PNG_PARAMS = saved


def _truthset_frames(r, background: bool, frames=None) -> list[float]:
    """Seconds per frame of a truth set written by ``write_frames`` (frame k: from the start of its render to the
    start of the next; the last frame's up to its files written, without the set's own end: truth tables, contact
    sheet, manifest and rename, printed apart)."""
    import renderlab.pipeline as pipeline
    from renderlab.files.truthset import TruthSetWriter

    stamps, orig, end = [], r.render_spec, [0.0]

    def render_spec(spec, ss, **kw):
        stamps.append(time.perf_counter())
        return orig(spec, ss, **kw)

    def timed(fn, flush_first=False):
        def wrapper(writer, *a, **k):
            if flush_first:
                writer.flush()  # the last frame's files: part of that frame
            t0 = time.perf_counter()
            try:
                return fn(writer, *a, **k)
            finally:
                end[0] += time.perf_counter() - t0
        return wrapper

    saved = pipeline._contact_sheet_png, TruthSetWriter.add_table, TruthSetWriter._commit
    r.render_spec = render_spec
    pipeline._contact_sheet_png = timed(saved[0], flush_first=True)
    TruthSetWriter.add_table = timed(saved[1], flush_first=True)
    TruthSetWriter._commit = timed(saved[2])
    head = {"scenario": r.scenario.to_dict(), "seed": r.scenario.render.seed, "render_frame": r.plan.render_frame}
    try:
        with tempfile.TemporaryDirectory() as tmp:
            specs = [r.plan.frames[k] for k in frames] if frames else r.plan.frames
            pipeline.write_frames(Path(tmp) / "ts", r, specs, [r.seed_for(s.index) for s in specs], head=head,
                         background=background)
            stamps.append(time.perf_counter() - end[0])
    finally:
        del r.render_spec
        pipeline._contact_sheet_png, TruthSetWriter.add_table, TruthSetWriter._commit = saved
    print(f"    ({'background' if background else 'in the loop'}: the set's end, tables + contact sheet + manifest, "
          f"{end[0]:.2f} s)", flush=True)
    return np.diff(stamps).tolist()


def sphere_floor(mi, size: int, spp: int) -> float:
    """Seconds of a warm ``mi.render`` (``direct``) of a 1.31 M-triangle sphere (trimesh icosphere, 8 subdivisions)
    filling a ``size``² frame."""
    import drjit as dr
    import trimesh

    sph = trimesh.creation.icosphere(subdivisions=8, radius=1.0)
    scene = mi.load_dict({"type": "scene", "sun": {"type": "directional", "direction": [0.3, 0.2, -1.0]},
                          "body": {"type": "ply", "filename": _ply(sph)}})
    sensor = mi.load_dict({"type": "perspective", "fov_axis": "x", "fov": 16.0,
                           "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 8.5], target=[0, 0, 0], up=[0, 1, 0]),
                           "sampler": {"type": "independent", "sample_count": spp},
                           "film": {"type": "hdrfilm", "width": size, "height": size,
                                    "rfilter": {"type": "box"}, "pixel_format": "luminance"}})
    integ = mi.load_dict(DIRECT)
    for s in range(2):
        t0 = time.perf_counter()
        dr.eval(mi.render(scene, sensor=sensor, integrator=integ, spp=spp, seed=s))
        dr.sync_thread()
    return time.perf_counter() - t0


def _ply(mesh) -> str:
    path = Path(tempfile.mkdtemp()) / "sphere.ply"
    mesh.export(path)
    return str(path)


def _merged_backend(r):
    """A one-scene backend of ``r``'s world (tiles merged into the scene): the geometry the floor renders."""
    from renderlab.pipeline import make_backend
    from renderlab.render.mitsuba_backend import tile_design

    with tile_design("merged"):
        return make_backend(r.scenario, r.plan.static_scene, "mitsuba")


def descent_world(args) -> None:
    from renderlab.pipeline.frame_api import Renderer

    r = Renderer(REPO / "results" / "descent_navigation" / "scenario.toml", overrides=["render.spp=16", *args.set])
    merged = _merged_backend(r)
    times, floors, moved = [], [], np.array([0.3, -0.2, 0.1])
    r.frame(0)  # kernels compiled, first tiles built
    for shift in (np.zeros(3), moved):
        for k in range(r.n_frames):
            p = r.spec(k).pose
            t0 = time.perf_counter()
            r.frame(k, pose=(p.position_m + shift, p.rotation))
            times.append(time.perf_counter() - t0)
            if not shift.any():
                merged._set_sun(r.spec(k))
                floors.append(_floor(merged.mi, merged, r.spec(k), 16))
    t, f = np.array(times), np.array(floors)
    q = np.percentile(t, [50, 90, 100])
    print(f"descent-navigation world 256², 16 spp {' '.join(args.set)}, {len(t)} frames in memory (2 passes over the "
          f"descent): {len(t) / t.sum():.2f} frames/s; frame time median {q[0]:.3f} s, p90 {q[1]:.3f} s, worst "
          f"{q[2]:.3f} s; histogram (s): {np.histogram(t, bins=[0, 0.1, 0.2, 0.3, 0.4, 0.5, 1.0, 10.0])[0].tolist()} "
          f"for bins [0, .1, .2, .3, .4, .5, 1, 10]; mi.render direct of the same geometry: median {np.median(f):.3f} s, "
          f"API / floor per frame (planned poses): median {np.median(t[:len(f)] / f):.2f}x", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=4)
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--skip-full", action="store_true")
    ap.add_argument("--skip-descent", action="store_true")
    ap.add_argument("--skip-api", action="store_true", help="full EV5: only the renderlab-render bar")
    ap.add_argument("--repeats", type=int, default=2,
                    help="full EV5: interleaved timings per frame (median), and renderlab-render passes per file mode")
    ap.add_argument("--compressions", default="zip", help="renderlab-render bar: EXR compressions, e.g. zip,none")
    ap.add_argument("--file-settings", default="new",
                    help="renderlab-render bar: the files' zlib settings, new and/or old (before: ZIP level 4, PNG 3)")
    ap.add_argument("--writers", default="loop,background", help="renderlab-render bar: loop and/or background")
    ap.add_argument("--bar-frames", type=lambda v: [int(k) for k in v.split(",")], default=None,
                    help="renderlab-render bar: only these frame indices (comma-separated), e.g. 2,3")
    ap.add_argument("--set", action="append", default=[], help="KEY=VALUE override of the world(s) measured")
    args = ap.parse_args()
    print(f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}", flush=True)
    if not args.skip_descent:
        descent_world(args)
    if not args.skip_full:
        full_ev5(args)
    print(f"load average at the end {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
