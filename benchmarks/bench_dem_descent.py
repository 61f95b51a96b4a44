"""The DEM march's ``descent_levels`` (:mod:`renderlab.render.dem_march`): nodes per ray and frame time, 1 vs 2.

On the full EV5 scenario (``scenes/ev5_descent.toml``, 3201² DEM) the Mitsuba backend (default design: the DEM
march, :mod:`renderlab.render.mitsuba_dem`) renders descent frames ``--frames`` (of 4: 0 = 1000 m, 1 = 171 m, 2 = 29 m,
3 = 5 m) at ``--size``², ``--spp`` spp with the march's ``descent_levels`` set to each of ``--levels`` in turn,
``--repeats`` interleaved times (``backend.render`` only: kernels and read-back, no sensor or truth rows), and counts
the nodes the march visits per camera ray that hits the site (``MarchHit.iterations``; the frame's camera rays at
min(spp, 4) samples per pixel) and per shadow ray toward the sun from those hits (1 mm along the sun). Prints each setting's median seconds, its ratio to ``descent_levels = 1`` timed
next to it, and the load average before and after.

Usage::

    .venv/bin/python benchmarks/bench_dem_descent.py [--frames 0,1,3] [--levels 1,2,3] [--size 1024] [--spp 16]
        [--repeats 3]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))


def node_counts(backend, spec, site, spp: int) -> tuple[float, float]:
    """Mean nodes visited per camera ray that hits the site, and per shadow ray from those hits."""
    import drjit as dr
    from bench_dem_march import camera_rays, to_site

    mi = backend.mi
    march = backend._two.surfaces[0][0]
    ray = camera_rays(backend, spec, spp)
    o, d = to_site(mi, dr, site, backend.origin, ray)
    h = march.intersect(o, d, ray.maxt)
    sun = site.R_body_from_site.T @ np.asarray(spec.sun.direction_render, float)
    sun = sun / np.linalg.norm(sun)
    so = mi.Vector3f(*[h.p[i] + 1e-3 * float(sun[i]) for i in range(3)])
    sd = mi.Vector3f(*[dr.zeros(type(h.p[0]), dr.width(h.p[0])) + float(sun[i]) for i in range(3)])
    sh = march._march(so, sd, None, 0.0, nearest=False)
    hit = np.array(h.valid)
    return float(np.array(h.iterations)[hit].mean()), float(np.array(sh.iterations)[hit].mean())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", default="0,1,3")
    ap.add_argument("--levels", default="1,2,3")
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    from bench_frame_api import _sets

    from renderlab.pipeline.frame_api import Renderer

    print(f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}", flush=True)
    levels = [int(v) for v in args.levels.split(",")]
    r = Renderer(REPO / "scenes" / "ev5_descent.toml", overrides=_sets(args.size, args.spp, 4))
    for k in (int(v) for v in args.frames.split(",")):
        spec = r.spec(k)
        r.frame(k)
        backend, scene = r.backend_for(spec)
        march = backend._two.surfaces[0][0]
        site = scene.tiled[0].site
        times: dict[int, list[float]] = {lv: [] for lv in levels}
        nodes = {}
        for lv in levels:
            march.descent = lv
            nodes[lv] = node_counts(backend, spec, site, min(args.spp, 4))
            backend.render(spec, seed=1)  # this setting's kernels
        for _ in range(args.repeats):
            for lv in levels:
                march.descent = lv
                t0 = time.perf_counter()
                backend.render(spec, seed=1)
                times[lv].append(time.perf_counter() - t0)
        base = np.array(times[levels[0]])
        for lv in levels:
            t = np.array(times[lv])
            print(f"frame {k}: descent_levels {lv}: nodes per camera / shadow ray {nodes[lv][0]:.1f} / "
                  f"{nodes[lv][1]:.1f}; backend.render median {np.median(t):.2f} s ({np.round(t, 2).tolist()}), "
                  f"/ descent_levels {levels[0]} run next to it: median {np.median(t / base):.2f}x", flush=True)
        march.descent = 2
    print(f"load average at the end {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
