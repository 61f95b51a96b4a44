"""EV5 descent truth frames: today's path vs the tiled site (levels of detail) + cached world, side by side.

Each configuration runs in its own child process (so its load, build and peak resident memory are its own),
one after the other in one run of this script, on the same descent frames at the same resolution and spp:

* ``old``: ``world.site.lod = false`` (the full-resolution site in every frame), ``world.build_cache = false``
  (world built in the process), numpy rays (``MitsubaBackend.ray_path = "numpy"``): the code before issue 19.
* ``old_drjit`` (with ``--paths``): the full site, Dr.Jit rays (the ray change alone).
* ``new_cold``: tiles with levels of detail, Dr.Jit rays, world cache empty (built and stored).
* ``new_warm``: the same in a later process: the world comes from the cache.

Per configuration: world build (or cache load) seconds, Mitsuba scene load seconds, seconds per frame
(scene update included), facets of the site in each frame, peak resident set of the process, and seconds
per frame *including its share* of build + load over the descent. Ratios against ``old`` are printed.

Usage::

    .venv/bin/python benchmarks/bench_ev5_descent.py [--world full|medium] [--frames N] [--size PX] [--spp S]
        [--paths old,new_cold,new_warm]

``full`` (default): the world of scenes/ev5_descent.toml (1 m global facets, 64 m site at 2 cm cells,
21.8 M facets); ``medium``: 2 m facets, 5 cm cells. Frames: ``trajectory.frames = N`` spread geometrically
in altitude from 1 km to 5 m. The world cache of the run is a fresh temporary folder (``RENDERLAB_CACHE``).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
PATHS = {"old": (False, "numpy", False), "old_drjit": (False, "drjit", True),
         "new_cold": (True, "drjit", True), "new_warm": (True, "drjit", True)}


def _sets(args, lod: bool, cache: bool) -> list[str]:
    s = args.size
    sets = [f"trajectory.frames={args.frames}", f"camera.width={s}", f"camera.height={s}",
            f"camera.fx={4871.6 * s / 1024}", f"camera.fy={4871.6 * s / 1024}", f"camera.cx={(s - 1) / 2}",
            f"camera.cy={(s - 1) / 2}", f"render.spp={args.spp}", f"world.site.lod={str(lod).lower()}",
            f"world.build_cache={str(cache).lower()}"]
    if args.world == "medium":
        sets += ["world.facet_m=2.0", "world.site.cell_m=0.05", "world.landmarks.2.spacing_m=0.06"]
    return sets


def child(args) -> None:
    """One configuration; prints one JSON line."""
    from renderlab.pipeline import make_backend
    from renderlab.render.mitsuba_backend import MitsubaBackend
    from renderlab.scenario import load_scenario
    from renderlab.worlds.ev5 import make_plan

    lod, rays, cache = PATHS[args.child]
    MitsubaBackend.ray_path = rays
    sc, base = load_scenario(REPO / "scenes" / "ev5_descent.toml", _sets(args, lod, cache))
    t0 = time.perf_counter()
    plan = make_plan(sc, base)
    t_build = time.perf_counter() - t0
    t0 = time.perf_counter()
    backend = make_backend(sc, plan.static_scene, "mitsuba")
    t_load = time.perf_counter() - t0
    frames = []
    for k, spec in enumerate(plan.frames):
        t0 = time.perf_counter()
        backend.render(spec, seed=k)
        dt = time.perf_counter() - t0
        meta = plan.frame_meta(spec, plan.static_scene)["ev5"]
        site = meta["lod"]["n_faces"] if "lod" in meta else int(len(plan.model.site.heights_m) - 1) ** 2 * 2
        frames.append({"altitude_m": meta["altitude_m"], "s": dt, "site_facets": site})
        print(f"  [{args.child}] frame {k}: {meta['altitude_m']:.0f} m, {dt:.1f} s, site facets {site}",
              file=sys.stderr, flush=True)
    print(json.dumps({"path": args.child, "build_s": t_build, "load_s": t_load, "frames": frames,
                      "peak_rss_gb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6,
                      "n_global_facets": int(len(plan.model.shape.faces))}))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--world", choices=["medium", "full"], default="full")
    ap.add_argument("--frames", type=int, default=3)
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--paths", default="old,new_cold,new_warm")
    ap.add_argument("--child", choices=list(PATHS), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        return child(args)
    print(f"EV5 {args.world} world, {args.frames} descent frames at {args.size}², {args.spp} spp; "
          f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}", flush=True)
    results = {}
    with tempfile.TemporaryDirectory(prefix="bench_ev5_cache_") as cache:
        env = {**os.environ, "RENDERLAB_CACHE": cache}
        for name in args.paths.split(","):
            cmd = [sys.executable, __file__, "--child", name, "--world", args.world, "--frames", str(args.frames),
                   "--size", str(args.size), "--spp", str(args.spp)]
            out = subprocess.run(cmd, env=env, stdout=subprocess.PIPE, text=True, check=True).stdout
            results[name] = r = json.loads(out.strip().splitlines()[-1])
            per = [f["s"] for f in r["frames"]]
            share = (r["build_s"] + r["load_s"] + sum(per)) / len(per)
            r["per_frame_s"], r["with_share_s"] = sum(per) / len(per), share
            print(f"{name:9s}: build {r['build_s']:.1f} s, load {r['load_s']:.1f} s, frames "
                  f"{', '.join(f'{x:.1f}' for x in per)} s (mean {r['per_frame_s']:.1f}); with its share of build + "
                  f"load {share:.1f} s/frame; peak RSS {r['peak_rss_gb']:.2f} GB; site facets per frame "
                  f"{[f['site_facets'] for f in r['frames']]}", flush=True)
    if "old" in results:
        o = results["old"]
        for name, r in results.items():
            if name != "old":
                print(f"old / {name}: per frame {o['per_frame_s'] / r['per_frame_s']:.1f}x, including the share of "
                      f"build + load {o['with_share_s'] / r['with_share_s']:.1f}x, peak RSS "
                      f"{o['peak_rss_gb']:.2f} -> {r['peak_rss_gb']:.2f} GB")
    print(f"load average at the end {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
