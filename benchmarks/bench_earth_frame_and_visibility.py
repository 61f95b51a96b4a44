"""Seconds per 1 MP Earth frame and per 24 h coastline-visibility case, with the side-by-side split of
each (GSHHG parse vs index builds; per frame: scene build = GSHHG clip + albedo raster + tile meshes, vs
Mitsuba render, vs coastline truth). Frame 0 includes Mitsuba's JIT compilation; later frames are warm.

Usage: .venv/bin/python benchmarks/bench_earth_frame_and_visibility.py [--size 1024] [--frames 2] [--spp 4]
       [--clouds 0.67] [--skip-render] [--skip-visibility]
"""

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
    ap.add_argument("--clouds", type=float, default=0.0, help="world.cloud_cover of the rendered frames")
    ap.add_argument("--skip-render", action="store_true")
    ap.add_argument("--skip-visibility", action="store_true")
    a = ap.parse_args()
    from renderlab.pipeline import make_backend
    from renderlab.scenario import load_scenario
    from renderlab.worlds.earth import make_plan
    from renderlab.worlds.earth.gshhg import load_gshhg
    from renderlab.worlds.earth.visibility import VisibilityOptions, visibility_sweep, visible_images

    T = time.perf_counter
    import numpy as np
    import shapely
    from roaring_landmask import LandmaskProvider, Shapes

    t0 = T()
    mp = shapely.from_wkb(Shapes.wkb(LandmaskProvider.Gshhg))
    t1 = T()
    np.asarray(mp.geoms)
    t2 = T()
    shapely.get_parts(mp)
    t3 = T()
    print(f"GSHHG WKB decode {t1 - t0:.2f} s; polygons as an array: MultiPolygon.geoms {t2 - t1:.2f} s vs "
          f"shapely.get_parts {t3 - t2:.2f} s (ratio {(t2 - t1) / (t3 - t2):.1f})")
    del mp
    t0 = T()
    g = load_gshhg()
    t1 = T()
    g.land_tree
    t2 = T()
    g.coast_tree
    g.coast_coords()
    t3 = T()
    print(f"load_gshhg {t1 - t0:.2f} s | land STRtree {t2 - t1:.2f} s | global coast chunks + STRtree (visibility "
          f"only) {t3 - t2:.2f} s | total {t3 - t0:.2f} s (once per process)")
    if not a.skip_render:
        sc, base = load_scenario(REPO / "scenes/earth_leo.toml", [
            f"camera.width={a.size}", f"camera.height={a.size}", f"trajectory.frames={a.frames}",
            f"render.spp={a.spp}", f"world.cloud_cover={a.clouds}"])
        plan = make_plan(sc, base)
        for spec in plan.frames:
            t0 = T()
            scene = plan.scene(plan.scene_key(spec))
            t1 = T()
            out = make_backend(sc, scene, "mitsuba").render(spec, seed=0)
            t2 = T()
            plan.frame_rows(spec, out)
            t3 = T()
            print(f"frame {spec.index} {a.size}x{a.size} spp {a.spp} clouds {a.clouds}: scene {t1 - t0:.2f} s, "
                  f"render {t2 - t1:.2f} s, coastline truth {t3 - t2:.2f} s, total {t3 - t0:.2f} s; "
                  f"render : scene = {(t2 - t1) / (t1 - t0):.2f}")
    for opt in () if a.skip_visibility else (VisibilityOptions(), VisibilityOptions(daylight_only=True),
                                             VisibilityOptions(daylight_only=True, cloud_cover=0.67)):
        t0 = T()
        row, _ = visible_images(45.0, 30.0, opt, g)
        t1 = T()
        visibility_sweep([45.0], [5, 10, 20, 30, 45, 60], opt, g, progress=False)
        t2 = T()
        print(f"24 h / 30 s (2880 images), 45 deg, daylight={opt.daylight_only} clouds={opt.cloud_cover}: "
              f"one 30 deg FOV case {t1 - t0:.2f} s, six-FOV row {t2 - t1:.2f} s "
              f"({(t2 - t1) / 6:.2f} s per case); 30 deg -> {row}")


if __name__ == "__main__":
    main()
