"""The DEM ray march (:mod:`renderlab.render.dem_march`) against the LOD tiles and Mitsuba's floor, one run.

On the full EV5 scenario (``scenes/ev5_descent.toml``: 64 m site at 2 cm, a 3201² DEM, 20.5 M facets), frame
``--frame`` (default 1: the 171 m frame of ``bench_frame_breakdown.py --frames 4``, whose tile set is 9.6 M level-0
facets) at ``--size``², ``--spp`` spp:

* **pyramid**: :func:`build_pyramid` of the site's heights and the upload (:class:`DemMarch`), once per site;
* **rays**: the frame's camera rays as the backend makes them (:class:`renderlab.render.mitsuba_rays.CameraRays`,
  every sample of every pixel: W·H·spp rays with the per-pixel Cranley–Patterson shifts), evaluated once and
  handed to each tracer (not timed); shadow rays from each tracer's own hits toward the sun (origin moved 1 mm
  along the sun direction, as a shadow-ray epsilon);
* **march**: primary rays (``intersect``: hit, t, cell, triangle, barycentrics, point) and shadow rays
  (``occluded``), the first call apart (kernel compilation), then ``--repeats`` timed calls;
* **tiles**: the two-scene path (``tile_design = "two"``) (:class:`renderlab.render.mitsuba_two_scene.TileScene`):
  ``update`` from another frame's tile set to this frame's (tile meshes built for the first time, concatenation,
  upload, Embree's build), then the same primary rays (``ray_intersect_preliminary``) and shadow rays
  (``ray_test``) in the tile scene, timed like the march;
* **floor**: a warm ``mi.render`` (Mitsuba's C++ ``direct``) of the same geometry (static bodies + this frame's tiles
  in one scene), as ``bench_frame_breakdown.py`` times it;
* **frames**: ``Renderer.frame`` of the frame right after another frame (the tile set changes), with
  ``tile_design = "two"`` and the default, the DEM march (:mod:`renderlab.render.mitsuba_dem`), ``--repeats``
  interleaved calls each;
* agreement of the march with the tile scene on the same primary rays (level-0 tiles are the DEM itself); rays hit
  by one of them only are checked against the float64 ray oracle on the DEM's cells around the hit.

Usage::

    nice -n 5 .venv/bin/python benchmarks/bench_dem_march.py [--frame 1] [--size 1024] [--spp 16] [--repeats 2]

Prints the wall and CPU seconds (this process, all threads: less sensitive to other jobs), the ratios and the load
average (``uptime``) before and after.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))

SHADOW_EPS_M = 1e-3


def _uptime() -> str:
    return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()


class Sec(float):
    """Wall seconds (the float's value) with the CPU seconds of this process over the same interval (``cpu``: all
    its threads; less sensitive than the wall time to the other jobs on the machine)."""

    cpu: float = 0.0


def _clock() -> tuple[float, float]:
    return time.perf_counter(), time.process_time()


def _since(start: tuple[float, float]) -> Sec:
    out = Sec(time.perf_counter() - start[0])
    out.cpu = time.process_time() - start[1]
    return out


def _timed(fn, sync):
    start = _clock()
    out = fn()
    sync(out)
    return out, _since(start)


def _fmt(d: dict) -> str:
    return ", ".join(f"{k} {v:.2f} (cpu {v.cpu:.2f})" for k, v in d.items())


def floor_sec(mi, backend, spec, spp: int) -> Sec:
    """A warm ``mi.render`` (``direct``) of ``backend``'s scene from ``spec``'s camera (as ``bench_frame_api._floor``:
    one untimed call, then one timed), wall and CPU seconds."""
    import drjit as dr
    from bench_ev5_descent import _sensor
    from bench_frame_api import DIRECT

    sensor, integ = _sensor(mi, backend, spec, spp), mi.load_dict(DIRECT)
    for seed in range(2):
        start = _clock()
        dr.eval(mi.render(backend.scene, sensor=sensor, integrator=integ, spp=spp, seed=seed))
        dr.sync_thread()
    return _since(start)


def camera_rays(backend, spec, spp: int):
    """The frame's W·H·spp sample rays in the backend's render frame − origin (evaluated), as its radiance pass."""
    mi, dr = backend.mi, backend.dr
    from renderlab.render.mitsuba_rays import FramePose, aligned_f32

    cam = spec.camera
    cr = backend._camera_rays(cam)
    pose = FramePose(mi, dr, spec.pose.rotation.as_matrix(), np.asarray(spec.pose.position_m, float) - backend.origin,
                     backend.settings.near_clip_m, backend.settings.far_clip_m)
    n = cam.width * cam.height * spp
    idx = dr.arange(mi.UInt32, n)
    pix = idx // spp
    shift = mi.Float(aligned_f32(np.random.default_rng(1).random((cam.width * cam.height, 2))))
    ray = cr.world_rays(cr.sample_directions(pix, cr.offsets(pix, idx - pix * spp, shift)), pose)
    dr.eval(ray.o, ray.d, ray.maxt)
    return ray


def to_site(mi, dr, site, origin, ray):
    """Rays in the site frame (render frame = the site body's frame): p_s = Rᵀ(p + origin − o_site), d_s = Rᵀ d."""
    R = site.R_body_from_site
    c = np.asarray(origin, float) - site.origin_m
    o = [sum(float(R[k, a]) * (ray.o[k] + float(c[k])) for k in range(3)) for a in range(3)]
    d = [sum(float(R[k, a]) * ray.d[k] for k in range(3)) for a in range(3)]
    o, d = mi.Vector3f(*o), mi.Vector3f(*d)
    dr.eval(o, d)
    return o, d


def march_times(march, o, d, maxt, sun_site, repeats: int) -> dict:
    dr = march.dr

    def primary():
        return march.intersect(o, d, maxt)

    def sync_hit(h):
        dr.eval(h.valid, h.t, h.i, h.j, h.tri, h.b1, h.b2, *h.p, h.iterations)
        dr.sync_thread()

    out = {}
    hit, out["primary first (compile)"] = _timed(primary, sync_hit)
    s = [float(v) for v in sun_site]
    t_shadow = dr.select(hit.valid, dr.inf, 0.0)

    def shadow():
        p = march.jit.Array3f(hit.p[0], hit.p[1], hit.p[2])
        return march.occluded(p, march.jit.Array3f(*s), t_shadow, t_min=SHADOW_EPS_M)

    def sync(b):
        dr.eval(b)
        dr.sync_thread()

    _, out["shadow first (compile)"] = _timed(shadow, sync)
    for k in range(repeats):
        hit, out[f"primary {k}"] = _timed(primary, sync_hit)
        _, out[f"shadow {k}"] = _timed(shadow, sync)
    return out, hit


def tile_times(backend, spec, other, ray, sun_render, repeats: int) -> dict:
    mi, dr = backend.mi, backend.dr
    two = backend._two
    two.update(other)
    dr.sync_thread()
    out = {}
    _, out["update (meshes + build)"] = _timed(lambda: two.update(spec), lambda _: dr.sync_thread())

    def primary():
        return two.scene.ray_intersect_preliminary(ray, coherent=True)

    def sync_pi(pi):
        dr.eval(pi.t, pi.prim_index, pi.prim_uv, pi.shape_index)
        dr.sync_thread()

    s = mi.Vector3f(*[float(v) for v in sun_render])
    for k in range(repeats):
        pi, out[f"primary {k}"] = _timed(primary, sync_pi)
        p = ray.o + ray.d * pi.t + s * SHADOW_EPS_M
        sray = mi.Ray3f(p, s)
        sray.maxt = dr.select(pi.is_valid(), dr.inf, 0.0)
        _, out[f"shadow {k}"] = _timed(lambda sray=sray, pi=pi: two.scene.ray_test(sray, pi.is_valid()),
                                       lambda b: (dr.eval(b), dr.sync_thread()))
    return out, pi


def oracle_hits(site, o, d, p) -> np.ndarray:
    """Float64 Möller–Trumbore (the lab's ray oracle) of rays ``o``, ``d`` (site frame) against the DEM's 5×5 cells
    around the points ``p``: True where one of their triangles is hit."""
    from renderlab.render.ray_oracle import _moller_trumbore

    h, c, x0 = site.heights_m.astype(np.float32).astype(np.float64), site.cell_m, site.x0_m
    out = np.zeros(len(o), bool)
    for k in range(len(o)):
        i0, j0 = (int(np.floor((p[k, a] - x0) / c)) - 2 for a in (0, 1))
        i, j = np.meshgrid(np.arange(max(i0, 0), min(i0 + 5, site.n - 1)),
                           np.arange(max(j0, 0), min(j0 + 5, site.n - 1)))
        i, j = i.ravel(), j.ravel()
        v = lambda a, b, i=i, j=j: np.stack([x0 + (i + a) * c, x0 + (j + b) * c, h[j + b, i + a]], -1)  # noqa: E731
        T = np.concatenate([np.stack([v(0, 0), v(1, 0), v(1, 1)], 1), np.stack([v(0, 0), v(1, 1), v(0, 1)], 1)])
        out[k] = np.isfinite(_moller_trumbore(o[k:k + 1], d[k:k + 1], T, 0.0)[0]).any()
    return out


def agreement(hit, pi, site, o_s, d_s, n_check: int = 200) -> str:
    """Hit/miss and t of the march vs the tile scene on the same rays; up to ``n_check`` rays hit by one tracer only
    checked against the float64 oracle."""
    a, b = np.array(hit.valid, bool), np.array(pi.is_valid(), bool)
    ta, tb = np.array(hit.t, np.float64), np.array(pi.t, np.float64)
    both = a & b
    dt = np.abs(ta[both] - tb[both])
    q = np.percentile(dt, [50, 99, 99.99]) if both.any() else [np.nan] * 3
    out = (f"march vs tile scene on {len(a)} rays: hits {a.sum()} / {b.sum()}; |dt| median {q[0]:.1e}, p99 {q[1]:.1e}, "
           f"p99.99 {q[2]:.1e}, max {dt.max():.1e} m; hit by one only:")
    for name, sel, t in (("march", a & ~b, ta), ("tiles", b & ~a, tb)):
        idx = np.nonzero(sel)[0][:n_check]
        o = np.stack([np.array(c, np.float64)[idx] for c in o_s], 1)
        d = np.stack([np.array(c, np.float64)[idx] for c in d_s], 1)
        ok = oracle_hits(site, o, d, o + t[idx, None] * d)
        out += f" {name} {int(sel.sum())} (of {len(idx)} checked, the float64 oracle hits the DEM there: {int(ok.sum())});"
    return out


def kernels(r, args, spec, other, floor) -> None:
    """The pyramid, the march and the two-scene tile path on the frame's rays, against ``floor()`` timed right after."""
    from renderlab.render.dem_march import DemMarch, build_pyramid, jit_module

    backend, _ = r.backend_for(spec)
    mi, dr = backend.mi, backend.dr
    site = r.plan.static_scene.tiled[0].site
    t0 = time.perf_counter()
    pyr = build_pyramid(site.heights_m, site.x0_m, site.cell_m)
    t1 = time.perf_counter()
    march = DemMarch(pyr, jit=jit_module(mi.variant()))
    print(f"pyramid (once per site): build {t1 - t0:.2f} s ({pyr.levels} levels, {pyr.maxima.nbytes / 1e6:.0f} MB), "
          f"upload {time.perf_counter() - t1:.2f} s", flush=True)
    ray = camera_rays(backend, spec, args.spp)
    o_s, d_s = to_site(mi, dr, site, backend.origin, ray)
    sun_render = np.asarray(spec.sun.direction_render, float)
    m, hit = march_times(march, o_s, d_s, ray.maxt, site.R_body_from_site.T @ sun_render, args.repeats)
    print("march (s): " + _fmt(m), flush=True)
    it = np.array(hit.iterations)
    print(f"  nodes visited per primary ray: mean {it.mean():.1f}, p99 {np.percentile(it, 99):.0f}, max {it.max()}; "
          f"hits {int(np.array(hit.valid).sum())}", flush=True)
    t, pi = tile_times(backend, spec, other, ray, sun_render, args.repeats)
    print("tiles, the two-scene path (s): " + _fmt(t), flush=True)
    print("  " + agreement(hit, pi, site, o_s, d_s), flush=True)
    del pi, hit, ray, o_s, d_s, march
    backend._two.update(other)  # the 9.6 M-facet tile structure freed
    f = floor()
    for unit, get in (("wall", float), ("cpu", lambda v: v.cpu)):
        best = lambda d, k, get=get: min(get(v) for n, v in d.items() if n.startswith(k) and "first" not in n)  # noqa: E731
        mp, ms, tp, ts = best(m, "primary"), best(m, "shadow"), best(t, "primary"), best(t, "shadow")
        tb, ff = get(t["update (meshes + build)"]), get(f)
        print(f"site intersection per frame, {unit} s (best of {args.repeats}): march primary {mp:.2f} + shadow "
              f"{ms:.2f} = {mp + ms:.2f}; tiles build {tb:.2f} + primary {tp:.2f} + shadow {ts:.2f} = "
              f"{tb + tp + ts:.2f}; floor right after {ff:.2f}")
        print(f"  ratios to the floor: march {(mp + ms) / ff:.2f}x, tiles {(tb + tp + ts) / ff:.2f}x (build alone "
              f"{tb / ff:.2f}x); march / tiles {(mp + ms) / (tb + tp + ts):.2f}; march / tile traversal alone "
              f"{(mp + ms) / (tp + ts):.2f}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frame", type=int, default=1, help="descent frame (of 4) to trace; 1 is the 171 m frame")
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--repeats", type=int, default=2)
    args = ap.parse_args()
    print(f"{os.cpu_count()} cores; {_uptime()}", flush=True)
    from bench_frame_api import _merged_backend, _sets

    from renderlab.pipeline.frame_api import Renderer
    from renderlab.render.mitsuba_backend import tile_design

    with tile_design("two"):  # r: the LOD tiles in a second scene, the design the march is compared with
        r = Renderer(REPO / "scenes" / "ev5_descent.toml", overrides=_sets(args.size, args.spp, 4))
        r.frame(3 if args.frame != 3 else 0)  # the backend is made with that design
    spec, other = r.spec(args.frame), r.spec(3 if args.frame != 3 else 0)
    tiled = r.plan.static_scene.tiled[0]
    site = tiled.site
    facets = tiled.lod_summary(tiled.select(spec.camera, spec.pose))["n_faces"]
    print(f"site DEM {site.heights_m.shape[1]} x {site.heights_m.shape[0]} at {site.cell_m} m "
          f"({2 * (site.n - 1) ** 2 / 1e6:.1f} M facets); frame {args.frame}: camera "
          f"{float(site.to_site(spec.pose.position_m)[2]):.0f} m above the site plane, {facets / 1e6:.2f} M tile "
          f"facets; {args.size}², {args.spp} spp = {args.size ** 2 * args.spp / 1e6:.1f} M rays", flush=True)
    merged = _merged_backend(r)  # the floor's scene: static bodies + this frame's tiles, built once
    merged._set_sun(spec)

    def floor() -> Sec:
        return floor_sec(merged.mi, merged, spec, args.spp)

    kernels(r, args, spec, other, floor)
    frames = frame_times(r, args, spec, other, floor)
    for name, v in frames.items():
        if name != "floor":
            ratio = np.array(v) / np.array(frames["floor"])
            cpu = np.array([x.cpu for x in v]) / np.array([x.cpu for x in frames["floor"]])
            print(f"Renderer.frame, {name}: {', '.join(f'{x:.2f} (cpu {x.cpu:.2f})' for x in v)} s; / the floor timed "
                  f"next to it: wall {', '.join(f'{x:.2f}' for x in ratio)}x (median {np.median(ratio):.2f}x), cpu "
                  f"{', '.join(f'{x:.2f}' for x in cpu)}x (median {np.median(cpu):.2f}x)")
    print(_uptime())


def frame_times(r, args, spec, other, floor) -> dict:
    """``Renderer.frame`` of the frame, each call right after ``other`` (the tile set changes), with tile_design = "two"
    (``r``) and with ``tile_design = "dem"`` (a second Renderer of the same scenario; its first frame, untimed, builds
    the pyramid and the site's mesh), and ``floor()``, interleaved ``--repeats`` times."""
    from bench_frame_api import _sets

    from renderlab.pipeline.frame_api import Renderer
    from renderlab.render.mitsuba_backend import tile_design

    out = {"two scenes": [], "dem (default)": [], "floor": []}
    with tile_design("dem"):
        rd = Renderer(REPO / "scenes" / "ev5_descent.toml", overrides=_sets(args.size, args.spp, 4))
        t0 = time.perf_counter()
        rd.frame(other.index)
        print(f"dem design: first frame (pyramid, site mesh, kernels) {time.perf_counter() - t0:.2f} s", flush=True)
    for _ in range(args.repeats):
        for name, rr in (("two scenes", r), ("dem (default)", rd)):
            rr.frame(other.index)
            start = _clock()
            rr.frame(spec.index)
            out[name].append(_since(start))
        out["floor"].append(floor())
        print("  " + ", ".join(f"{k} {v[-1]:.2f} s (cpu {v[-1].cpu:.2f})" for k, v in out.items()), flush=True)
    rd.close()
    return out


if __name__ == "__main__":
    main()
