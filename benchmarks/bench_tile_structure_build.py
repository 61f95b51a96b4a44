"""A frame's tile set as a flat mesh vs a ``shapegroup`` + ``instance``: Embree build and traversal, side by side.

The full EV5 scenario's frame ``--frame`` (default 1: the 171 m frame, 9.6 M level-0 tile facets at 1024²) gives the
tile set (:class:`renderlab.render.mitsuba_tiles.TileArrays`: the same float32 arrays the lab renders). Each
configuration loads a scene holding only those facets, timed (``mi.load_dict`` + ``dr.sync_thread``: Mitsuba builds the
structure at load; a top-level mesh gets the scene's spatial-split build, a shape group Embree's default quality),
then ``ray_intersect_preliminary`` of ``--rays`` incoherent camera rays (uniform sub-pixel positions, seeded), best of
two, and checks that both find the same hits (count and mean distance). Alternated ``--repeats`` times.

Usage::

    .venv/bin/python benchmarks/bench_tile_structure_build.py [--frame 1] [--size 1024] [--rays 4194304] [--repeats 2]
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


def _mesh(mi, V, F):
    from renderlab.render.mitsuba_rays import aligned_f32

    m = mi.Mesh("tiles", len(V), len(F) // 3)
    p = mi.traverse(m)
    p["vertex_positions"] = type(p["vertex_positions"])(aligned_f32(V))
    p["faces"] = type(p["faces"])(F)
    p.update()
    return m


def _rays(mi, spec, origin, n: int):
    from renderlab.render.mitsuba_rays import aligned_f32

    cam, pose = spec.camera, spec.pose
    rng = np.random.default_rng(0)
    u, v = rng.uniform(-0.5, cam.width - 0.5, n), rng.uniform(-0.5, cam.height - 0.5, n)
    d = np.stack([(u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy, np.ones(n)], 1) @ pose.rotation.as_matrix().T
    d /= np.linalg.norm(d, axis=1)[:, None]
    o = np.asarray(pose.position_m, float) - origin
    return mi.Ray3f(mi.Point3f(*[mi.Float(np.full(n, c, np.float32)) for c in o]),
                    mi.Vector3f(*[mi.Float(aligned_f32(d[:, k])) for k in range(3)]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frame", type=int, default=1)
    ap.add_argument("--frames", type=int, default=4, help="descent frames of the scenario (4: 1000/171/29/5 m)")
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--rays", type=int, default=4 * 1024 * 1024)
    ap.add_argument("--repeats", type=int, default=2)
    args = ap.parse_args()
    from bench_frame_api import _sets

    from renderlab.pipeline.frame_api import Renderer

    print(f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}", flush=True)
    r = Renderer(REPO / "scenes" / "ev5_descent.toml", overrides=_sets(args.size, 16, args.frames))
    spec = r.spec(args.frame)
    b, _ = r.backend_for(spec)
    mi, dr = b.mi, b.dr
    tiles = b._tiles.tiles
    V, F, _ = tiles.merged(0, list(tiles.wanted(spec)[0]))
    print(f"frame {args.frame}: {len(F) // 3 / 1e6:.2f} M tile facets, {len(V) / 1e6:.2f} M vertices", flush=True)
    ray = _rays(mi, spec, b.origin, args.rays)
    group = {"g": {"type": "shapegroup"}, "inst": {"type": "instance", "shapegroup": {"type": "ref", "id": "g"}}}
    for _ in range(args.repeats):
        for label in ("flat", "shapegroup"):
            m = _mesh(mi, V, F)
            t0 = time.perf_counter()
            if label == "flat":
                sc = mi.load_dict({"type": "scene", "tiles": m}, optimize=False)
            else:
                sc = mi.load_dict({"type": "scene", "g": {**group["g"], "tiles": m}, "inst": group["inst"]},
                                  optimize=False)
            dr.sync_thread()
            t_build, ts = time.perf_counter() - t0, []
            for _k in range(2):
                t0 = time.perf_counter()
                pi = sc.ray_intersect_preliminary(ray, coherent=False)
                dr.eval(pi.t)
                dr.sync_thread()
                ts.append(time.perf_counter() - t0)
            t = np.array(pi.t)
            hit = np.isfinite(t) & (t < 1e30)
            print(f"  {label:10s}: build {t_build:.2f} s, {args.rays / 1e6:.1f} M incoherent rays {min(ts):.2f} s, "
                  f"hits {hit.mean():.4f}, mean distance {t[hit].mean():.4f} m, load {os.getloadavg()[0]:.1f}",
                  flush=True)


if __name__ == "__main__":
    main()
