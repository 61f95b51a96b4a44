"""Seconds per rendered frame of a truth-perturbed ``retina_vs_spc`` run: the world loaded once per process vs per run.

Each repetition draws a new truth perturbation (position, velocity, attitude of the scenario's ``[perturbations]``;
run index = repetition) and renders the run's frames into a temporary truth set two ways, side by side and
interleaved in one process:

* **loaded** -- what the study does (:func:`renderlab.campaign.cache.render_frames` with this process's
  :class:`~renderlab.pipeline.frame_api.Renderer`: world plan built and scene loaded once, reused for every pose);
* **per run** -- a fresh ``Renderer`` per run (world plan built and the renderer's scene loaded again each run:
  the cost of treating each perturbed run as its own scenario).

Both write the same files (same seeds). Prints the median and minimum per rendered frame (render + sensor + truth
tables + files) and the one-off world-plan and scene-load times. Temporary files only; nothing is kept::

    .venv/bin/python benchmarks/bench_truth_perturbed_runs.py                      # published scenario, 3 repeats
    .venv/bin/python benchmarks/bench_truth_perturbed_runs.py --repeats 1          # smoke test
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("scenario", nargs="?", default=str(REPO / "results/retina_vs_spc_truth_perturbed/scenario.toml"))
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--set", action="append", default=[], help="scenario override key=value (repeatable)")
    args = ap.parse_args(argv)

    from renderlab.campaign.cache import render_frames
    from renderlab.campaign.perturb import draw_perturbation
    from renderlab.campaign.plan import run_seed_sequence
    from renderlab.pipeline.frame_api import Renderer
    from renderlab.scenario import load_scenario, scenario_from_dict, truth_dict
    from renderlab.campaign.run_truth import perturbed_specs

    sc, base = load_scenario(args.scenario, args.set)
    truth = scenario_from_dict(truth_dict(sc.to_dict()), "benchmark truth scenario")
    print(f"command: {' '.join(sys.argv)}")
    print(f"cores: {os.cpu_count()}  load average: {' '.join(f'{x:.1f}' for x in os.getloadavg())}")
    print(f"camera {truth.camera.width}x{truth.camera.height}, spp {truth.render.spp}, world {truth.world.kind}")
    t = time.perf_counter()
    world = Renderer(truth, base)
    print(f"world plan (once per process): {time.perf_counter() - t:.1f} s, {len(world.plan.frames)} frames per run")
    t = time.perf_counter()
    world.backend_for(world.plan.frames[0])
    print(f"scene load (once per process): {time.perf_counter() - t:.1f} s")
    times = {"loaded": [], "per run": []}
    with tempfile.TemporaryDirectory() as tmp:
        for rep in range(args.repeats):
            draw = draw_perturbation(sc.perturbations, run_seed_sequence(sc.campaign.seed or 0, rep).spawn(4)[0])
            specs = perturbed_specs(world.plan.frames, draw)
            for name in ("loaded", "per run") if rep % 2 == 0 else ("per run", "loaded"):
                t = time.perf_counter()
                w = world if name == "loaded" else Renderer(truth, base)
                render_frames(w, Path(tmp) / f"{name.replace(' ', '_')}_{rep}", specs)
                times[name].append((time.perf_counter() - t) / len(specs))
            print(f"  repeat {rep}: loaded {times['loaded'][-1]:.2f} s/frame, per run {times['per run'][-1]:.2f} s/frame "
                  f"(load average {os.getloadavg()[0]:.1f})", flush=True)
    for name, v in times.items():
        print(f"{name:>8}: median {statistics.median(v):.2f} s per rendered frame, min {min(v):.2f} s ({len(v)} runs)")
    lo, pr = statistics.median(times["loaded"]), statistics.median(times["per run"])
    print(f"per run / loaded (medians): {pr / lo:.2f}x;  scene loads in the loaded world: {world.loads}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
