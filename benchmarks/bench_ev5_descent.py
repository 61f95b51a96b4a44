"""EV5 descent rendering speed, measured side by side in one run.

1. Frames per second along the descent with the Mitsuba scene loaded once and updated in place
   (sun + rays per frame, as the pipeline does) vs a scene reloaded for every frame; prints the ratio.
2. Seconds per 1 MP (1024²) frame at 16 samples per pixel, scene already loaded.

Usage::

    .venv/bin/python benchmarks/bench_ev5_descent.py [--world medium|full] [--frames N] [--size PX]

``medium`` (default): 2 m global facets, 64 m site at 5 cm cells (1.6 M site facets);
``full``: the world of scenes/ev5_descent.toml (1 m facets, 2 cm cells, 20.5 M site facets).
World building (shape, site, catalog) is timed separately and excluded from the frame rates.
"""

from __future__ import annotations

import argparse
import os
import resource
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--world", choices=["medium", "full"], default="medium")
    ap.add_argument("--frames", type=int, default=4)
    ap.add_argument("--size", type=int, default=512, help="image size for the in-place vs reload comparison")
    args = ap.parse_args()

    from renderlab.pipeline import make_backend
    from renderlab.scenario import load_scenario
    from renderlab.worlds.ev5 import make_plan

    sets = [f"trajectory.frames={args.frames}", f"camera.width={args.size}", f"camera.height={args.size}",
            f"camera.fx={4871.6 * args.size / 1024}", f"camera.fy={4871.6 * args.size / 1024}",
            f"camera.cx={(args.size - 1) / 2}", f"camera.cy={(args.size - 1) / 2}"]
    if args.world == "medium":
        sets += ["world.facet_m=2.0", "world.site.cell_m=0.05", "world.landmarks.2.spacing_m=0.06"]
    sc, base = load_scenario(REPO / "scenes" / "ev5_descent.toml", sets)
    t0 = time.perf_counter()
    plan = make_plan(sc, base)
    t_world = time.perf_counter() - t0
    n_tri = sum(len(b.faces) for b in plan.static_scene.bodies)
    print(f"world {args.world}: {n_tri / 1e6:.2f} M facets, built in {t_world:.1f} s; "
          f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}")

    t0 = time.perf_counter()
    backend = make_backend(sc, plan.static_scene, "mitsuba")
    t_load = time.perf_counter() - t0
    backend.render(plan.frames[0], seed=0)  # JIT warm-up, excluded from both rates
    t0 = time.perf_counter()
    for k, spec in enumerate(plan.frames):
        backend.render(spec, seed=k)
    t_inplace = (time.perf_counter() - t0) / len(plan.frames)
    del backend

    t0 = time.perf_counter()
    for k, spec in enumerate(plan.frames):
        b = make_backend(sc, plan.static_scene, "mitsuba")
        b.render(spec, seed=k)
        del b
    t_reload = (time.perf_counter() - t0) / len(plan.frames)
    print(f"scene load {t_load:.2f} s; {args.size}² at {sc.render.spp} spp over {len(plan.frames)} descent frames:")
    print(f"  loaded once, updated in place: {1 / t_inplace:.3f} frames/s ({t_inplace:.2f} s/frame)")
    print(f"  reloaded per frame:            {1 / t_reload:.3f} frames/s ({t_reload:.2f} s/frame)")
    print(f"  ratio in-place / reload:       {t_reload / t_inplace:.1f}x")

    # 1 MP at 16 spp: same world, a 1024² camera (the toml's), the last descent frame's pose and sun
    from renderlab.geometry.camera import CameraModel
    from renderlab.render.scene import FrameSpec

    sc1, _ = load_scenario(REPO / "scenes" / "ev5_descent.toml",
                           [s for s in sets if not s.startswith("camera.")] + ["render.spp=16"])
    cam = CameraModel.from_dict(sc1.camera.model_dump())
    spec = FrameSpec(0, plan.frames[-1].pose, cam, plan.frames[-1].sun)
    b1 = make_backend(sc1, plan.static_scene, "mitsuba")
    b1.render(spec, seed=0)
    t0 = time.perf_counter()
    reps = 2
    for k in range(reps):
        b1.render(spec, seed=k + 1)
    t_mp = (time.perf_counter() - t0) / reps
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6
    print(f"1 MP (1024²) frame at 16 spp: {t_mp:.2f} s/frame (mean of {reps}, scene loaded)")
    print(f"peak resident memory of this process: {peak:.2f} GB; load average now {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
