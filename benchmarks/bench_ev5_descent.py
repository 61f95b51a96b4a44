"""EV5 descent truth frames: today's path vs the tiled site (levels of detail) + cached world, side by side.

Each configuration runs in its own child process (so its load, build and peak resident memory are its own),
one after the other in one run of this script, on the same descent frames at the same resolution and spp:

* ``old``: ``world.site.lod = false`` (the full-resolution site in every frame), ``world.build_cache = false``
  (world built in the process), numpy rays (``MitsubaBackend.ray_path = "numpy"``), Mitsuba's ``path``
  integrator at ``max_depth = 2`` (``MitsubaBackend.integrator = "path"``): the code before ``rl_direct_sun``.
* ``old_drjit`` (with ``--paths``): the full site, Dr.Jit rays, ``path`` (the ray change alone).
* ``new_cold``: tiles with levels of detail, Dr.Jit rays, the direct-sun integrator (``rl_direct_sun``:
  primary + shadow ray, renderlab/render/mitsuba_direct.py), world cache empty (built and stored).
* ``new_path``: tiles, Dr.Jit rays, world from the cache, ``path`` (the code before the direct-sun change).
* ``new_warm``: tiles, Dr.Jit rays, ``rl_direct_sun``, world from the cache: today's code.
* ``new_small_pass``: ``new_warm`` with ``MitsubaBackend.samples_per_pass = 2**22`` (wavefronts of 4 M samples
  instead of one of W·H·spp up to 16 M): the wavefront size against throughput.

Per configuration: world build (or cache load) seconds, Mitsuba scene load seconds, seconds per frame
(tile update + render) and its CPU time (all threads of the process: on a shared machine the children run one after
the other under different loads, and CPU time is less sensitive to other jobs than the wall clock), the tile update (``_set_sun``: tiles written into the mesh, acceleration structure
rebuilt) and a sun-only parameter update timed apart, facets of the site in each frame, peak resident set
of the process, and seconds per frame *including its share* of build + load over the descent; with tiles,
the acceleration-structure rebuild alone (the last frame's tiles written back unchanged, ``params.update()``). Ratios against
``old`` are printed. ``--floor``: on ``new_warm``'s (and ``old_drjit``'s) frames, ``mi.render`` of the same
loaded scene (the frame's tiles) with a perspective sensor, radiance only, per integrator (``direct``:
Mitsuba's C++ direct illumination, one emitter sample, no BSDF sample; ``rl_direct_sun``; ``path``), the
first frame's calls after an untimed warm-up: what Mitsuba's own renderer needs for these frames on this
machine, the floor of any lab path. ``--spp-pass``: the wavefront size (samples per pass).

Usage::

    .venv/bin/python benchmarks/bench_ev5_descent.py [--world full|medium] [--frames N] [--size PX] [--spp S]
        [--paths old,new_cold,new_path,new_warm] [--floor direct,rl_direct_sun] [--spp-pass N]

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
#: path → (site levels of detail, ray path, world cache, integrator)
PATHS = {"old": (False, "numpy", False, "path"), "old_drjit": (False, "drjit", True, "path"),
         "new_path": (True, "drjit", True, "path"), "new_cold": (True, "drjit", True, "auto"),
         "new_warm": (True, "drjit", True, "auto"), "new_small_pass": (True, "drjit", True, "auto")}
#: mi.render integrators of ``--floor`` (Mitsuba's own renderer on the same loaded scene, radiance only)
FLOORS = {"direct": {"type": "direct", "emitter_samples": 1, "bsdf_samples": 0, "hide_emitters": True},
          "rl_direct_sun": {"type": "rl_direct_sun"},
          "path": {"type": "path", "max_depth": 2, "hide_emitters": True}}


def _sensor(mi, backend, spec, spp: int):
    """A perspective sensor of ``spec``'s pinhole camera (square pixels) in the backend's shifted scene."""
    import math

    import numpy as np

    cam, T = spec.camera, np.eye(4)
    T[:3, :3] = spec.pose.rotation.as_matrix() @ np.diag([-1.0, -1.0, 1.0])  # Mitsuba: +x left, +y up
    T[:3, 3] = np.asarray(spec.pose.position_m, float) - backend.origin
    W, H = cam.width, cam.height
    return mi.load_dict({
        "type": "perspective", "fov_axis": "x", "fov": math.degrees(2 * math.atan(W / 2 / cam.fx)),
        "principal_point_offset_x": (W / 2 - (cam.cx + 0.5)) / W,
        "principal_point_offset_y": (H / 2 - (cam.cy + 0.5)) / H,
        "near_clip": backend.settings.near_clip_m, "far_clip": backend.settings.far_clip_m,
        "to_world": mi.ScalarTransform4f(T.tolist()),
        "sampler": {"type": "independent", "sample_count": spp},
        "film": {"type": "hdrfilm", "width": W, "height": H, "rfilter": {"type": "box"}, "pixel_format": "luminance"}})


def _floors(backend, spec, spp: int, names: list[str], warm: bool) -> dict:
    """Seconds of ``mi.render`` of the backend's current scene (this frame's tiles) per integrator in ``names``
    (``warm``: one untimed call first, so the timed one excludes tracing and kernel compilation)."""
    import drjit as dr
    import numpy as np

    mi, out = backend.mi, {}
    sensor = _sensor(mi, backend, spec, spp)
    for name in names:
        integ = mi.load_dict(FLOORS[name])
        for k in range(2 if warm else 1):
            t0, c0 = time.perf_counter(), time.process_time()
            img = mi.render(backend.scene, sensor=sensor, integrator=integ, spp=spp, seed=k)
            dr.eval(img)
            mean = float(np.array(img).mean())
            out[name], out[name + "_cpu_s"] = time.perf_counter() - t0, time.process_time() - c0
        out[name + "_mean_radiance"] = mean
    return out


def _sets(args, lod: bool, cache: bool) -> list[str]:
    s = args.size
    sets = [f"trajectory.frames={args.frames}", f"camera.width={s}", f"camera.height={s}",
            f"camera.fx={4871.6 * s / 1024}", f"camera.fy={4871.6 * s / 1024}", f"camera.cx={(s - 1) / 2}",
            f"camera.cy={(s - 1) / 2}", f"render.spp={args.spp}", f"world.site.lod={str(lod).lower()}",
            f"world.build_cache={str(cache).lower()}"]
    if args.world == "medium":
        sets += ["world.facet_m=2.0", "world.site.cell_m=0.05", "world.landmarks.2.spacing_m=0.06"]
    return sets


def _rebuild_same_tiles(backend) -> list[float]:
    """Seconds of ``params.update()`` after writing the last frame's own tile vertices back into the tiled mesh
    (same tiles, so only Mitsuba's acceleration-structure rebuild of the whole scene is timed), twice."""
    import drjit as dr
    import numpy as np

    p, out = backend.params, []
    for _ in range(2):
        v = p["tiled0.vertex_positions"]
        p["tiled0.vertex_positions"] = type(v)(np.array(v))
        t0 = time.perf_counter()
        p.update()
        dr.sync_thread()
        out.append(time.perf_counter() - t0)
    return out


def child(args) -> None:
    """One configuration; prints one JSON line."""
    from renderlab.pipeline import make_backend
    from renderlab.render.mitsuba_backend import MitsubaBackend
    from renderlab.scenario import load_scenario
    from renderlab.worlds.ev5 import make_plan

    lod, rays, cache, integrator = PATHS[args.child]
    MitsubaBackend.ray_path, MitsubaBackend.integrator = rays, integrator
    if args.spp_pass:
        MitsubaBackend.samples_per_pass = args.spp_pass
    if args.child == "new_small_pass":  # new_warm with a wavefront of 4 M samples (1 MP, 16 spp: 4 passes)
        MitsubaBackend.samples_per_pass = 1 << 22
    sc, base = load_scenario(REPO / "scenes" / "ev5_descent.toml", _sets(args, lod, cache))
    t0 = time.perf_counter()
    plan = make_plan(sc, base)
    t_build = time.perf_counter() - t0
    t0 = time.perf_counter()
    backend = make_backend(sc, plan.static_scene, "mitsuba")
    t_load = time.perf_counter() - t0
    frames = []
    floors = [f for f in args.floor.split(",") if f] if args.child in ("new_warm", "old_drjit") else []
    for k, spec in enumerate(plan.frames):
        t0, c0 = time.perf_counter(), time.process_time()
        backend._set_sun(spec)  # the tile update (when the tile set changed) and the sun, timed apart
        t_update = time.perf_counter() - t0
        t0 = time.perf_counter()
        out = backend.render(spec, seed=k)  # its own _set_sun: same tiles, so the sun only
        dt, cpu = time.perf_counter() - t0, time.process_time() - c0
        t0 = time.perf_counter()
        backend._set_sun(spec)  # same tiles again: what a sun-only parameter update costs
        t_sun = time.perf_counter() - t0
        meta = plan.frame_meta(spec, plan.static_scene)["ev5"]
        site = meta["lod"]["n_faces"] if "lod" in meta else int(len(plan.model.site.heights_m) - 1) ** 2 * 2
        rec = {"altitude_m": meta["altitude_m"], "s": dt + t_update, "cpu_s": cpu, "render_s": dt, "update_s": t_update,
               "sun_update_s": t_sun, "site_facets": site, "mean_radiance": float(out.radiance.mean())}
        if floors:
            rec["mi_render_s"] = _floors(backend, spec, args.spp, floors, warm=(k == 0))
        frames.append(rec)
        print(f"  [{args.child}] frame {k}: {meta['altitude_m']:.0f} m, {dt + t_update:.1f} s (tile update "
              f"{t_update:.2f} s, render {dt:.1f} s, sun-only update {t_sun:.2f} s), site facets {site}"
              + (f", mi.render {rec['mi_render_s']}" if floors else ""), file=sys.stderr, flush=True)
    rebuild = _rebuild_same_tiles(backend) if backend._tiles is not None else None
    print(json.dumps({"path": args.child, "build_s": t_build, "load_s": t_load, "frames": frames,
                      "rebuild_same_tiles_s": rebuild, "samples_per_pass": MitsubaBackend.samples_per_pass,
                      "peak_rss_gb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6,
                      "n_global_facets": int(len(plan.model.shape.faces))}))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--world", choices=["medium", "full"], default="full")
    ap.add_argument("--frames", type=int, default=3)
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--paths", default="old,new_cold,new_path,new_warm")
    ap.add_argument("--floor", default="direct,rl_direct_sun",
                    help="mi.render integrators timed on new_warm's (and old_drjit's) frames; '' for none")
    ap.add_argument("--spp-pass", type=int, default=0, help="MitsubaBackend.samples_per_pass (0: its default)")
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
                   "--size", str(args.size), "--spp", str(args.spp), "--floor", args.floor,
                   "--spp-pass", str(args.spp_pass)]
            out = subprocess.run(cmd, env=env, stdout=subprocess.PIPE, text=True, check=True).stdout
            results[name] = r = json.loads(out.strip().splitlines()[-1])
            per, upd = [f["s"] for f in r["frames"]], [f["update_s"] for f in r["frames"]]
            cpus = [f["cpu_s"] for f in r["frames"]]
            share = (r["build_s"] + r["load_s"] + sum(per)) / len(per)
            r["per_frame_s"], r["with_share_s"] = sum(per) / len(per), share
            r["per_frame_cpu_s"] = sum(f["cpu_s"] for f in r["frames"]) / len(per)
            print(f"{name:9s}: build {r['build_s']:.1f} s, load {r['load_s']:.1f} s, frames "
                  f"{', '.join(f'{x:.1f}' for x in per)} s (mean {r['per_frame_s']:.1f}); with its share of build + "
                  f"load {share:.1f} s/frame; CPU time per frame (all threads) "
                  f"{', '.join(f'{c:.1f}' for c in cpus)} s (mean {r['per_frame_cpu_s']:.1f}); peak RSS {r['peak_rss_gb']:.2f} GB; site facets per frame "
                  f"{[f['site_facets'] for f in r['frames']]}; tile updates "
                  f"{', '.join(f'{u:.2f}' for u in upd)} s", flush=True)
            if r.get("rebuild_same_tiles_s"):
                print(f"    acceleration-structure rebuild with the same tiles (last frame's, beside the "
                      f"{r['n_global_facets'] / 1e6:.2f} M-facet global mesh): "
                      + ", ".join(f"{x:.2f}" for x in r["rebuild_same_tiles_s"]) + " s", flush=True)
            for f in r["frames"]:
                if "mi_render_s" in f:
                    print(f"    {f['altitude_m']:.0f} m: lab {f['s']:.1f} s; mi.render (same scene, radiance only) "
                          + ", ".join(f"{k} {v:.1f} s ({f['mi_render_s'][k + '_cpu_s']:.1f} CPU s)"
                                      for k, v in f["mi_render_s"].items() if k in FLOORS), flush=True)
    if "old" in results:
        o = results["old"]
        for name, r in results.items():
            if name != "old":
                print(f"old / {name}: per frame {o['per_frame_s'] / r['per_frame_s']:.1f}x (CPU time "
                      f"{o['per_frame_cpu_s'] / r['per_frame_cpu_s']:.1f}x), including the share of "
                      f"build + load {o['with_share_s'] / r['with_share_s']:.1f}x, peak RSS "
                      f"{o['peak_rss_gb']:.2f} -> {r['peak_rss_gb']:.2f} GB")
        if "new_warm" in results and any("mi_render_s" in f for f in results["new_warm"]["frames"]):
            fr = results["new_warm"]["frames"]
            for name in [n for n in FLOORS if n in fr[0].get("mi_render_s", {})]:
                mean = sum(f["mi_render_s"][name] for f in fr) / len(fr)
                cpu = sum(f["mi_render_s"][name + "_cpu_s"] for f in fr) / len(fr)
                print(f"old / mi.render {name} (new_warm's scene): per frame {o['per_frame_s'] / mean:.1f}x, CPU time "
                      f"{o['per_frame_cpu_s'] / cpu:.1f}x (mi.render {mean:.1f} s, {cpu:.1f} CPU s per frame: the floor of "
                      f"any lab path on this scene; 10x needs {o['per_frame_s'] / 10:.1f} s, {o['per_frame_cpu_s'] / 10:.1f} CPU s)")
    if "new_path" in results and "new_warm" in results:
        a, b = results["new_path"], results["new_warm"]
        print(f"new_path / new_warm (the integrator alone): per frame {a['per_frame_s'] / b['per_frame_s']:.2f}x "
              f"(CPU time {a['per_frame_cpu_s'] / b['per_frame_cpu_s']:.2f}x)")
    print(json.dumps({"results": results}), file=sys.stderr)
    print(f"load average at the end {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
