#!/usr/bin/env python
"""What a tile write costs in Mitsuba, with and without the static mesh in the scene, flat or instanced.

The lab's tiled surfaces (:mod:`renderlab.render.mitsuba_tiles`) write a frame's tiles into one mesh of a loaded
scene with ``mi.traverse`` and ``params.update()``. On the full EV5 world that update costs 1–2 s per frame at
load 1–2 (``bench_ev5_descent.py``), more than the render. This benchmark isolates the cause on synthetic meshes:
a "tile" mesh (a 131 × 131 vertex height field, 33 800 facets, the size of the last EV5 descent frame's tiles) is
rewritten (its vertices moved by 1e-4) and ``params.update()`` timed, in scenes that hold

* ``tile only``: nothing else;
* ``flat``: the tile mesh and a static mesh of ``--static`` facets as a second top-level shape;
* ``instanced``: the static mesh inside a ``shapegroup`` referenced by one ``instance`` (Embree then keeps a
  separate acceleration structure for the group, which a tile write need not touch);

each with a 256² ``direct`` render first (so the structures exist). Printed: the median update time of
``--repeats`` writes per configuration, the ratio to ``tile only``, and Mitsuba's version. Timed side by side in one
process, configurations one after the other (each is its own scene), wall clock.

Measured with Mitsuba 3.9.1 (benchmarks/README.md): the update time grows with the *static* mesh in both the flat
and the instanced scene, i.e. Mitsuba's Embree back end rebuilds the instanced group's structure too; ``perf``
shows Embree's SAH BVH builder as the dominant cost of the update in both.

Run:  .venv/bin/python benchmarks/bench_mitsuba_tile_update.py                       # static 80 k, 320 k, 1.3 M facets
      .venv/bin/python benchmarks/bench_mitsuba_tile_update.py --static 200 --repeats 1  # smoke
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np


def height_field(n: int, z0: float) -> tuple[np.ndarray, np.ndarray]:
    """(float32 vertices (n², 3), uint32 faces (2 (n−1)², 3)) of a wavy n × n grid on [−1, 1]² at height z0."""
    x, y = np.meshgrid(np.linspace(-1.0, 1.0, n), np.linspace(-1.0, 1.0, n))
    z = z0 + 0.01 * np.sin(7.0 * x) * np.cos(5.0 * y)
    V = np.c_[x.ravel(), y.ravel(), z.ravel()].astype(np.float32)
    i = np.arange(n * n).reshape(n, n)
    a, b, c, d = i[:-1, :-1].ravel(), i[:-1, 1:].ravel(), i[1:, :-1].ravel(), i[1:, 1:].ravel()
    return V, np.r_[np.c_[a, b, c], np.c_[b, d, c]].astype(np.uint32)


def _mesh(mi, name: str, V: np.ndarray, F: np.ndarray):
    m = mi.Mesh(name, len(V), len(F))
    p = mi.traverse(m)
    p["vertex_positions"] = mi.Float(V.ravel())
    p["faces"] = mi.UInt32(F.ravel())
    p.update()
    return m


def update_times(mi, mode: str, static_n: int, repeats: int) -> list[float]:
    """Seconds of ``params.update()`` after each of ``repeats`` writes of the tile mesh's vertices."""
    Vt, Ft = height_field(131, 0.05)
    desc = {"type": "scene", "integrator": {"type": "direct"},
            "sensor": {"type": "perspective", "fov": 40.0,
                       "to_world": mi.ScalarTransform4f().look_at([0, 0, 3], [0, 0, 0], [0, 1, 0]),
                       "film": {"type": "hdrfilm", "width": 256, "height": 256}},
            "sun": {"type": "directional", "direction": [0.3, 0.2, -1.0]}, "tile": _mesh(mi, "tile", Vt, Ft)}
    if mode != "tile only":
        Vs, Fs = height_field(static_n, 0.0)
        if mode == "instanced":
            desc["group"] = {"type": "shapegroup", "static": _mesh(mi, "static", Vs, Fs)}
            desc["instance"] = {"type": "instance", "shapegroup": {"type": "ref", "id": "group"}}
        else:
            desc["static"] = _mesh(mi, "static", Vs, Fs)
    scene = mi.load_dict(desc)
    np.asarray(mi.render(scene, spp=1))
    params = mi.traverse(scene)
    key = next(k for k in params.keys() if k.endswith("vertex_positions") and "tile" in k)
    out = []
    for r in range(repeats):
        params[key] = mi.Float(Vt.ravel() + np.float32(1e-4 * (r + 1)))
        t0 = time.perf_counter()
        params.update()
        out.append(time.perf_counter() - t0)
    np.asarray(mi.render(scene, spp=1))  # the scene still renders after the writes
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--static", default="201,400,807", help="static mesh grid sizes n (2 (n−1)² facets), comma-separated")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--variant", default="llvm_ad_mono")
    a = ap.parse_args(argv)
    import mitsuba as mi

    mi.set_variant(a.variant)
    mi.set_log_level(mi.LogLevel.Error)
    print(f"Mitsuba {mi.__version__}, {a.variant}; tile mesh 33 800 facets; median of {a.repeats} writes")
    base = statistics.median(update_times(mi, "tile only", 0, a.repeats))
    print(f"{'static facets':>14} {'configuration':>12} {'update (s)':>11} {'/ tile only':>12}")
    print(f"{0:>14} {'tile only':>12} {base:>11.4f} {1.0:>12.1f}")
    for n in (int(s) for s in a.static.split(",")):
        for mode in ("flat", "instanced"):
            t = statistics.median(update_times(mi, mode, n, a.repeats))
            print(f"{2 * (n - 1) ** 2:>14} {mode:>12} {t:>11.4f} {t / base:>12.1f}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
