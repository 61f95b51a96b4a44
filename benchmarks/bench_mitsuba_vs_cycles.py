#!/usr/bin/env python
"""Mitsuba vs Blender Cycles: seconds per frame at equal samples and at equal noise, one run.

Scene: ``scenes/analytic_sphere_box.toml`` (a Lambert sphere, a Lommel-Seeliger box, a plane), frame 0,
camera scaled to ``--size`` pixels wide (aspect and view of the scenario kept), direct sunlight,
1-px box filter. Both backends produce a full :class:`RenderedFrame` (truth-AOV pass at pixel centres +
radiance pass); the timings include that and, for Cycles, the file exchange with its worker process
(scene set-up, bpy import and Mitsuba's JIT compile are excluded: the first call of every configuration
is a warm-up). Repetitions are interleaved because the machine is shared.

Noise of a configuration: the rms over lit pixels of (L_seed1 − L_seed2)/√2, two renders with
different seeds (only pixels whose footprint is not uniform — edges, the sphere — are noisy: direct
light from a hard sun is otherwise exact). *Equal noise*: the Cycles time at the sample count whose
noise equals Mitsuba's at ``--spp`` (log-log interpolation between the measured Cycles sample counts).

``mitsuba`` renders with the lab's direct-sun integrator (``rl_direct_sun``, renderlab/render/mitsuba_direct.py);
``mitsuba-path`` is the same backend with Mitsuba's ``path`` integrator (``max_depth = 2``: the integrator before
the direct-sun change); ``mitsuba-numpy`` adds ``ray_path = "numpy"`` (numpy rays per sample: the code before
the Dr.Jit ray path), timed in the same run for the before/after ratios (``--skip-numpy`` leaves it out).

Run:  .venv/bin/python benchmarks/bench_mitsuba_vs_cycles.py                 # 256 px, 16 spp
      .venv/bin/python benchmarks/bench_mitsuba_vs_cycles.py --size 64 --repeats 1   # smoke
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]


def _scenario(size: int, spp: int):
    from renderlab.scenario import load_scenario

    k = size / 256.0
    sets = [f"camera.width={size}", f"camera.height={round(192 * k)}", f"camera.fx={262.0 * k}", f"camera.fy={258.0 * k}",
            f"camera.cx={(131.3 + 0.5) * k - 0.5}", f"camera.cy={(93.8 + 0.5) * k - 0.5}", f"render.spp={spp}"]
    return load_scenario(REPO / "scenes" / "analytic_sphere_box.toml", sets)


def _backend(renderer: str, size: int, spp: int):
    """``renderer`` is a registered renderer, ``mitsuba-path`` (Mitsuba's ``path`` integrator instead of the
    direct-sun one) or ``mitsuba-numpy`` (``path`` and the former numpy ray path: the code before the Dr.Jit ray path)."""
    from renderlab.pipeline import make_backend
    from renderlab.render.mitsuba_backend import MitsubaBackend
    from renderlab.worlds.base import make_plan

    sc, base = _scenario(size, spp)
    plan = make_plan(sc, base)
    old = renderer in ("mitsuba-numpy", "mitsuba-path")
    MitsubaBackend.integrator = "path" if old else "auto"
    try:
        be = make_backend(sc, plan.scene(0), "mitsuba" if old else renderer)
    finally:
        MitsubaBackend.integrator = "auto"
    if renderer == "mitsuba-numpy":
        be.ray_path = "numpy"
    return be, plan.frames[0]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--spp", type=int, default=16, help="Mitsuba's sample count (equal-samples comparison)")
    ap.add_argument("--cycles-spp", default="4,16,64", help="Cycles sample counts measured (comma-separated)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--skip-numpy", action="store_true", help="do not time Mitsuba's former numpy ray path")
    args = ap.parse_args()
    cyc_spp = sorted({int(v) for v in args.cycles_spp.split(",")} | {args.spp})
    configs = ([("mitsuba", args.spp), ("mitsuba-path", args.spp)]
               + ([] if args.skip_numpy else [("mitsuba-numpy", args.spp)])
               + [("cycles", s) for s in cyc_spp])
    backends = {}
    for name, spp in configs:
        t0 = time.perf_counter()
        backends[(name, spp)] = _backend(name, args.size, spp)
        print(f"set-up {name:8s} {spp:4d} spp: {time.perf_counter() - t0:6.2f} s")
    times = {c: [] for c in configs}
    frames = {}
    for c in configs:  # warm-up + the two seeds for the noise
        be, spec = backends[c]
        frames[c] = [be.render(spec, seed=s).radiance.astype(np.float64) for s in (11, 12)]
    for r in range(args.repeats):
        for c in configs[r % len(configs):] + configs[:r % len(configs)]:
            be, spec = backends[c]
            t0 = time.perf_counter()
            be.render(spec, seed=100 + r)
            times[c].append(time.perf_counter() - t0)
    ref = frames[configs[0]][0]
    lit = ref > 0.02 * np.percentile(ref, 99.9)
    noise = {c: float(np.sqrt(np.mean(((f[0] - f[1])[lit]) ** 2) / 2)) for c, f in frames.items()}
    med = {c: float(np.median(t)) for c, t in times.items()}
    H = frames[configs[0]][0].shape[0]
    print(f"\n{args.size}x{H} px, {args.repeats} repeats, lit pixels {int(lit.sum())}, load avg {os.getloadavg()[0]:.1f}")
    print(f"{'renderer':13s} {'spp':>5s} {'s/frame (median)':>17s} {'noise rms [W m^-2 sr^-1]':>26s}")
    for c in configs:
        print(f"{c[0]:13s} {c[1]:5d} {med[c]:17.3f} {noise[c]:26.4f}")
    m = configs[0]
    print(f"\nMitsuba path integrator / direct-sun integrator time = {med[('mitsuba-path', args.spp)] / med[m]:.2f}")
    if ("mitsuba-numpy", args.spp) in med:
        print(f"Mitsuba with numpy rays and path / now time = {med[('mitsuba-numpy', args.spp)] / med[m]:.2f}")
    print(f"\nequal samples ({args.spp} spp): Cycles / Mitsuba time = {med[('cycles', args.spp)] / med[m]:.2f}")
    cs = [c for c in configs if c[0] == "cycles"]
    ln, lt = np.log([noise[c] for c in cs]), np.log([med[c] for c in cs])
    order = np.argsort(ln)
    target = np.log(noise[m])
    if ln.min() <= target <= ln.max():
        t_eq = float(np.exp(np.interp(target, ln[order], lt[order])))
        spp_eq = float(np.exp(np.interp(target, ln[order], np.log([c[1] for c in cs])[order])))
        print(f"equal noise ({noise[m]:.4f}): Cycles needs ≈{spp_eq:.0f} spp, {t_eq:.3f} s/frame; "
              f"Cycles / Mitsuba time = {t_eq / med[m]:.2f}")
    else:
        print(f"equal noise: Mitsuba's noise {noise[m]:.4f} lies outside Cycles' measured range "
              f"[{np.exp(ln.min()):.4f}, {np.exp(ln.max()):.4f}]; widen --cycles-spp")
    for be, _ in backends.values():
        if hasattr(be, "close"):
            be.close()


if __name__ == "__main__":
    main()
