"""Runs per minute of the ``analytic_pointing`` campaign with 1 vs 2 local Dask workers (one run each).

    .venv/bin/python benchmarks/bench_campaign_workers.py [--runs 16] [--size 128]

Each configuration gets a fresh campaign folder (no truth cache shared), the same plan and seed. The
wall time includes starting the LocalCluster — what a user waits for. Each worker's thread pools
(Dr.Jit/Mitsuba, numba, BLAS) are capped at cores // workers (``DaskExecutor.threads_per_run``).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from renderlab.campaign.executors import DaskExecutor
from renderlab.campaign.plan import make_plan
from renderlab.campaign.runner import run_campaign
from renderlab.scenario import load_scenario

SCENE = Path(__file__).resolve().parents[1] / "scenes" / "analytic_sphere_box.toml"


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=16)
    ap.add_argument("--size", type=int, default=128, help="image width (height = 3/4)")
    a = ap.parse_args()
    w, h = a.size, a.size * 3 // 4
    sc, base = load_scenario(SCENE, [f"camera.width={w}", f"camera.height={h}", f"camera.fx={w * 1.03}",
                                     f"camera.fy={w * 1.02}", f"camera.cx={w / 2}", f"camera.cy={h / 2 - 1}",
                                     "render.spp=16", "trajectory.frames=2", "perturbations.position_sigma_m=[0.1,0.1,0.1]",
                                     "perturbations.attitude_sigma_deg=0.5", "perturbations.sun_direction_sigma_deg=2"])
    plan = make_plan(sc, base, a.runs, seed=1)
    rate = {}
    with tempfile.TemporaryDirectory() as tmp:
        for n in (1, 2):
            ex = DaskExecutor(workers=n)
            print(f"{n} worker(s) x {ex.threads_per_run} thread(s) per run", flush=True)
            t0 = time.perf_counter()
            res = run_campaign(plan, Path(tmp) / f"w{n}", executor=ex, progress=False)
            wall = time.perf_counter() - t0
            assert not res.failed, res.failed
            rate[n] = a.runs / wall * 60
            print(f"{n} worker(s): {a.runs} runs ({w}x{h}, 2 frames, 16 spp) in {wall:.1f} s "
                  f"= {rate[n]:.1f} runs/min (cluster start included)")
    print(f"ratio 2 workers / 1 worker: {rate[2] / rate[1]:.2f}")


if __name__ == "__main__":
    main()
