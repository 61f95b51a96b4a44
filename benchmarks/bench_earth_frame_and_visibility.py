"""Seconds per Earth frame (scene build: GSHHG clip + albedo raster + tile; render: Mitsuba) and per 24 h
visibility case. Usage: .venv/bin/python benchmarks/bench_earth_frame_and_visibility.py [--size 1024] [--frames 2]"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--frames", type=int, default=2)
    ap.add_argument("--spp", type=int, default=4)
    a = ap.parse_args()
    from renderlab.render.pipeline import make_backend
    from renderlab.scenario import load_scenario
    from renderlab.worlds.earth import make_plan
    from renderlab.worlds.earth.gshhg import load_gshhg
    from renderlab.worlds.earth.visibility import VisibilityOptions, visible_images

    t = time.perf_counter()
    g = load_gshhg()
    print(f"GSHHG load + index: {time.perf_counter() - t:.1f} s (once per process)")
    sc, base = load_scenario(REPO / "scenes/earth_leo.toml", [f"camera.width={a.size}", f"camera.height={a.size}",
                                                              f"trajectory.frames={a.frames}", f"render.spp={a.spp}"])
    plan = make_plan(sc, base)
    for spec in plan.frames:
        t0 = time.perf_counter()
        scene = plan.scene(plan.scene_key(spec))
        t1 = time.perf_counter()
        out = make_backend(sc, scene, "mitsuba").render(spec, seed=0)
        t2 = time.perf_counter()
        plan.frame_rows(spec, out)
        t3 = time.perf_counter()
        print(f"frame {spec.index} {a.size}x{a.size} spp {a.spp}: scene {t1 - t0:.2f} s, render {t2 - t1:.2f} s, "
              f"coastline truth {t3 - t2:.2f} s, total {t3 - t0:.2f} s")
    for opt in (VisibilityOptions(), VisibilityOptions(daylight_only=True, cloud_cover=0.67)):
        t0 = time.perf_counter()
        row, _ = visible_images(45.0, 30.0, opt, g)
        print(f"24 h / 30 s visibility, 45 deg, 30 deg FOV, daylight={opt.daylight_only} clouds={opt.cloud_cover}: "
              f"{time.perf_counter() - t0:.2f} s -> {row}")


if __name__ == "__main__":
    main()
