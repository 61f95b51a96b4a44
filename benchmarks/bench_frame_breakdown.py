"""Where a full EV5 frame's time goes: per stage of ``Renderer.frame`` and of the files ``renderlab render`` writes.

Every stage is timed in place (its function wrapped for this process only), frame by frame, on the full EV5 scenario
(``scenes/ev5_descent.toml``, 1.30 M global facets, 64 m site at 2 cm in tiles with levels of detail) at ``--size``²,
``--spp`` spp, through the real truth-set loop (:func:`renderlab.pipeline.write_frames`, which writes the files in a
background thread while the next frame renders; ``--sequential`` writes them in the loop):

* **tiles**: the tile selection (``TiledSite.select``: also called by the frame's metadata), the tile meshes built
  for the first time (``TileArrays._tile``: ``TiledSite.tile_mesh`` + the render-frame float32 arrays; cached hits
  cost nothing), their concatenation (``TileArrays.merged``), and Mitsuba's ``params.update()`` followed by
  ``dr.sync_thread`` (the tile scene's structure rebuild, i.e. Embree's build, plus the milliseconds of the sun
  update); ``backend: tiles + sun update`` is all of it (``MitsubaBackend._set_sun``, upload included). The process
  renders the last frame first (scene load, kernels), so frame 0 changes the tile set like the others and the last
  frame finds its tile meshes built;
* **render**: ``MitsubaBackend.render`` (all: the tile update above, the truth-AOV pass and the radiance passes);
* **sensor** (``expose``), **meta** (``frame_meta``), **truth rows** (``plan.frame_rows``: landmark truth);
* **files**: ``exr_channels``, ``write_exr`` (the scenario's ``render.exr_compression``), ``write_dn_png``,
  ``write_dn_preview`` (seconds in whichever thread runs them), and the manifest/tables/contact sheet at the end;
* the floor: a warm ``mi.render`` (Mitsuba's C++ ``direct``) of the same geometry (static bodies + the frame's tiles in
  one scene) and of a 1.31 M-triangle sphere filling the frame (the ``renderlab render`` bar).

Usage::

    .venv/bin/python benchmarks/bench_frame_breakdown.py [--frames 4] [--size 1024] [--spp 16] [--sequential]
        [--set KEY=VALUE ...]

Prints one line per frame and a table of seconds per stage; the load average before and after.
"""

from __future__ import annotations

import argparse
import functools
import os
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))

T: dict = defaultdict(float)  # stage -> seconds in the current frame
N: dict = defaultdict(int)


def _timed(owner, name: str, stage: str, sync=None) -> None:
    """Wrap ``owner.name`` so that its calls add their wall time to ``T[stage]`` (nested calls counted once)."""
    fn = getattr(owner, name)

    @functools.wraps(fn)
    def wrapper(*a, **k):
        t0 = time.perf_counter()
        try:
            return fn(*a, **k)
        finally:
            if sync is not None:
                sync()
            T[stage] += time.perf_counter() - t0
            N[stage] += 1

    setattr(owner, name, wrapper)


def instrument(mi) -> None:
    import drjit as dr

    import renderlab.pipeline.frame_api as fa
    from renderlab.files import imageio
    from renderlab.render import mitsuba_backend, mitsuba_tiles, scene
    from renderlab.sensor import model
    from renderlab.worlds.ev5 import tiles

    _timed(tiles.TiledSite, "select", "tiles: select")
    _timed(mitsuba_tiles.TileArrays, "_tile", "tiles: new meshes")
    _timed(mitsuba_tiles.TileArrays, "merged", "tiles: concatenate")
    _timed(mi.SceneParameters, "update", "tiles: params.update (BVH)", sync=dr.sync_thread)
    _timed(mitsuba_backend.MitsubaBackend, "render", "backend.render (all)")
    _timed(mitsuba_backend.MitsubaBackend, "_set_sun", "backend: tiles + sun update", sync=dr.sync_thread)
    _timed(model, "expose", "sensor")
    _timed(fa, "frame_meta", "meta")
    _timed(scene.RenderedFrame, "exr_channels", "files: exr_channels")
    for name, stage in (("write_exr", "files: EXR"), ("write_dn_png", "files: DN PNG"),
                        ("write_dn_preview", "files: preview PNG")):
        _timed(imageio, name, stage)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=4)
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--sequential", action="store_true", help="write each frame's files in the loop (no thread)")
    ap.add_argument("--set", action="append", default=[], help="KEY=VALUE override")
    args = ap.parse_args()
    print(f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}", flush=True)
    from bench_frame_api import _merged_backend, _sets

    import renderlab.pipeline as pipeline
    from renderlab.pipeline.frame_api import Renderer

    r = Renderer(REPO / "scenes" / "ev5_descent.toml", overrides=_sets(args.size, args.spp, args.frames) + args.set)
    r.frame(r.n_frames - 1)  # scene loaded, kernels compiled; frame 0 then changes the tile set like the others
    instrument(r.backend.mi)
    _timed(type(r.plan), "frame_rows", "truth rows")
    specs, seeds = r.plan.frames, [r.seed_for(s.index) for s in r.plan.frames]
    merged = _merged_backend(r)
    before = _floors(merged, specs, args)  # the floors before and after the loop: the load may change meanwhile
    ends = []
    orig = r.render_spec

    def render_spec(spec, ss, **kw):  # frame boundaries: the loop calls this once per frame
        ends.append((time.perf_counter(), dict(T)))
        return orig(spec, ss, **kw)

    r.render_spec = render_spec
    with tempfile.TemporaryDirectory() as tmp:
        head = {"scenario": r.scenario.to_dict(), "seed": r.scenario.render.seed, "render_frame": r.plan.render_frame}
        t0 = time.perf_counter()
        pipeline.write_frames(Path(tmp) / "ts", r, specs, seeds, head=head, background=not args.sequential)
        total = time.perf_counter() - t0
    ends.append((time.perf_counter(), dict(T)))
    facets = [sum(t.lod_summary(t.select(s.camera, s.pose))["n_faces"] for t in r.plan.static_scene.tiled) for s in specs]
    after = _floors(merged, specs, args)
    _report(args, r, ends, before, after, total, facets)
    print(f"load average at the end {os.getloadavg()[0]:.1f}")


def _floors(merged, specs, args) -> tuple[list[float], float]:
    """Warm ``mi.render`` (``direct``) seconds of each frame's geometry (one scene) and of the 1.31 M sphere."""
    from bench_frame_api import _floor, sphere_floor

    out = []
    for spec in specs:
        merged._set_sun(spec)
        out.append(_floor(merged.mi, merged, spec, args.spp))
    return out, sphere_floor(merged.mi, args.size, args.spp)


def _report(args, r, ends, before, after, total, facets) -> None:
    floors = (np.array(before[0]) + np.array(after[0])) / 2
    sphere = (before[1] + after[1]) / 2
    stages = sorted({k for _, d in ends for k in d})
    rows = []
    for k in range(len(ends) - 1):
        (t0, a), (t1, b) = ends[k], ends[k + 1]
        rows.append(({s: b.get(s, 0.0) - a.get(s, 0.0) for s in stages}, t1 - t0))
    mode = "sequential" if args.sequential else "background writer"
    print(f"full EV5 {args.size}², {args.spp} spp, {mode} {' '.join(args.set)}: loop {total:.2f} s for "
          f"{len(rows)} frames (the last frame's interval includes the manifest, tables and contact sheet)")
    print(f"  {'stage':28s} " + " ".join(f"{'frame ' + str(k):>9s}" for k in range(len(rows))))
    for s in stages:
        print(f"  {s:28s} " + " ".join(f"{d.get(s, 0.0):9.3f}" for d, _ in rows))
    print(f"  {'tile facets (M)':28s} " + " ".join(f"{f / 1e6:9.3f}" for f in facets))
    print(f"  {'wall per frame (loop)':28s} " + " ".join(f"{w:9.3f}" for _, w in rows))
    for label, (geo, sph) in (("before", before), ("after", after)):
        print(f"  {'mi.render same geo, ' + label:28s} " + " ".join(f"{f:9.3f}" for f in geo))
        print(f"  {'mi.render 1.31 M sphere, ' + label:28s} {sph:9.3f}")
    walls = np.array([w for _, w in rows])
    print(f"  loop wall / sphere floor per frame: {np.round(walls / sphere, 2).tolist()}; "
          f"/ same-geometry floor: {np.round(walls / floors, 2).tolist()} (floors: mean of before and after)")


if __name__ == "__main__":
    main()
