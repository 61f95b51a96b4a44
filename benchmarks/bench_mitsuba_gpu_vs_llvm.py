#!/usr/bin/env python
"""GPU (``cuda_ad_*``) vs CPU (``llvm_ad_*``): the same lab render path, the same frame, image equality and time.

Scene: ``scenes/analytic_sphere_box.toml`` frame 0, square ``--size`` camera (as the other Mitsuba
benchmarks), box filter at ``--spp`` and centre sampling at 1 spp, mono and RGB. For each colour the LLVM
backend and the CUDA backend render the frame with the same seed (same sub-pixel positions); the variant
is set before every call (Mitsuba's types follow the active variant). Checks, printed and written as
JSON (``--json``):

* ``max |L_cuda − L_llvm| / max L_llvm ≤ --tol`` (default 1e-5) for every configuration;
* how many pixels differ by more than ``tol · max L`` (a sample that grazes a silhouette can land on the
  other side in the other backend's float32 arithmetic: that pixel moves by L/spp), body ids equal,
  position AOV difference;
* seconds per frame, median of ``--repeats`` after one warm-up call, both backends in one run.

Exit status 0 when every check holds, 1 when one fails, 2 when no CUDA variant is usable (no GPU).

Run (a GPU machine, from the repository root; ``benchmarks/gpu_check.sh`` runs it):
      .venv/bin/python benchmarks/bench_mitsuba_gpu_vs_llvm.py --size 1024 --json gpu_vs_llvm.json
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
for p in (ROOT, ROOT / "benchmarks"):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--size", type=int, default=1024)
    p.add_argument("--spp", type=int, default=16)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--tol", type=float, default=1e-5, help="max |diff| / max radiance allowed (default 1e-5)")
    p.add_argument("--json", type=Path, default=None, help="write the figures here")
    p.add_argument("--against", choices=("cuda", "llvm"), default="cuda",
                   help="the device compared with LLVM (llvm: a smoke test of this script without a GPU)")
    return p.parse_args(argv)


def timed(mi, backend, frame, repeats):
    mi.set_variant(backend.variant)
    out = backend.render(frame, seed=7)  # warm-up (JIT compile) and the image compared
    t = []
    for _ in range(repeats):
        mi.set_variant(backend.variant)
        t0 = time.perf_counter()
        backend.render(frame, seed=7)
        t.append(time.perf_counter() - t0)
    return out, statistics.median(t)


def main(argv=None):
    args = parse_args(argv)
    from sphere_box_scene import lab_settings, load_inputs

    from renderlab.render.mitsuba_backend import MitsubaBackend
    from renderlab.render.variant import init_mitsuba

    scenario, scene, frame = load_inputs(args.size)
    mi = init_mitsuba("llvm_ad_mono")
    try:
        mi.set_variant(f"{args.against}_ad_mono")
    except Exception as exc:  # no GPU / driver
        print(f"no usable CUDA variant here: {' '.join(str(exc).split())}")
        return 2
    other = args.against
    rows, ok = [], True
    for colour in ("mono", "rgb"):
        for filt, spp in (("box", args.spp), ("center", 1)):
            res = {}
            for key, dev in (("llvm", "llvm"), ("cuda", other)):
                variant = f"{dev}_ad_{colour}"
                mi.set_variant(variant)
                be = MitsubaBackend(scene, lab_settings(scenario, variant, spp, filt))
                if be.variant != variant:
                    print(f"{variant} fell back to {be.variant}")
                    return 2
                be.ray_path = "drjit"
                res[key] = timed(mi, be, frame, args.repeats)
            (a, ta), (b, tb) = res["llvm"], res["cuda"]
            scale = float(np.max(a.radiance))
            diff = np.abs(b.radiance.astype(np.float64) - a.radiance)
            hit = (a.body_id >= 0) & (b.body_id >= 0)
            row = {"colour": colour, "filter": filt, "spp": spp, "size": args.size,
                   "max_rel_diff": float(diff.max() / scale),
                   "pixels_over_tol": int((diff > args.tol * scale).sum()),
                   "body_id_differences": int((a.body_id != b.body_id).sum()),
                   "position_max_diff_m": float(np.abs(a.position[hit] - b.position[hit]).max()),
                   "s_per_frame_llvm": ta, "s_per_frame_cuda": tb, "llvm_over_cuda": ta / tb}
            row["pass"] = row["max_rel_diff"] <= args.tol
            ok &= row["pass"]
            rows.append(row)
            print(f"{colour:4s} {filt:6s} {spp:3d} spp {args.size}^2: max|diff|/max {row['max_rel_diff']:.2e} "
                  f"({'PASS' if row['pass'] else 'FAIL'} at {args.tol:g}), {row['pixels_over_tol']} px over, "
                  f"{row['body_id_differences']} ids differ; LLVM {ta:.3f} s, {other.upper()} {tb:.3f} s "
                  f"({ta / tb:.1f}x)", flush=True)
    if args.json is not None:
        args.json.write_text(json.dumps({"command": " ".join(sys.argv), "rows": rows}, indent=1))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
