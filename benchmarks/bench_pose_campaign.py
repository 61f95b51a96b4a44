"""Unknown-satellite campaign: seconds per run when runs share one truth render (noise and prior errors only,
the truth cache serves every run after the first) vs when every run renders its own sequence (truth tumble
rate and initial attitude dispersed), measured side by side in one process.

    .venv/bin/python benchmarks/bench_pose_campaign.py [--runs 3] [--frames 8] [--repeats 2]

Scene: scenes/microsat_campaign.toml at 256×192 with ``--frames`` frames 4 s apart (the test sequence).
A 1-run warm-up campaign first pays the one-time costs (Mitsuba variant load and JIT, numba compilation), so
the first configuration timed is not charged for them; the two configurations then alternate ``--repeats``
times (the order swapped every repeat) and the median and minimum seconds per run are reported.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def sets(frames: int, truth_dispersed: bool) -> list[str]:
    out = [f"trajectory.frames={frames}", "trajectory.dt_s=4.0", "trajectory.v0_lvlh_mps=[0.01,-0.04,0.005]",
           "camera.width=256", "camera.height=192", "camera.fx=222", "camera.fy=222", "camera.cx=127.5",
           "camera.cy=95.5", "render.spp=2", "unknown_satellite.min_track_frames=4",
           "unknown_satellite.epsilon_px=15.0"]
    if not truth_dispersed:
        out += ["unknown_satellite.tumble_rate_sigma_frac=0", "unknown_satellite.initial_attitude_sigma_deg=0"]
    return out


def main() -> None:
    from renderlab.campaign.runner import run_campaign_file
    from renderlab.campaign.store import load_tables

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--frames", type=int, default=8)
    ap.add_argument("--repeats", type=int, default=2)
    args = ap.parse_args()
    configs = (("shared render", False), ("own render per run", True))
    res = {label: [] for label, _ in configs}
    with tempfile.TemporaryDirectory() as tmp:
        run_campaign_file(REPO / "scenes" / "microsat_campaign.toml", Path(tmp) / "warmup", 1,
                          overrides=sets(args.frames, False), workers=0, progress=False)
        for rep in range(args.repeats):
            for label, disp in (configs if rep % 2 == 0 else configs[::-1]):
                out = Path(tmp) / f"{label.replace(' ', '_')}_{rep}"
                t0 = time.perf_counter()
                run_campaign_file(REPO / "scenes" / "microsat_campaign.toml", out, args.runs,
                                  overrides=sets(args.frames, disp), workers=0, progress=False)
                dt = time.perf_counter() - t0
                hits = load_tables(out)["scores"].column("truth_cache_hit").to_pylist()
                res[label].append(dt / args.runs)
                print(f"repeat {rep} {label:20s}: {dt:7.1f} s for {args.runs} runs = {dt / args.runs:6.1f} s/run "
                      f"(truth cache hits {sum(hits)} of {len(hits)})")
    for label, v in res.items():
        print(f"{label:20s}: median {statistics.median(v):6.2f} s/run, min {min(v):6.2f} s/run")
    print(f"ratio own/shared (medians): {statistics.median(res['own render per run']) / statistics.median(res['shared render']):.2f}")


if __name__ == "__main__":
    main()
