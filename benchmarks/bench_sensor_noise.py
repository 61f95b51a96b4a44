"""``renderlab.sensor.model.expose`` with the per-pixel counter-based noise vs the former sequential stream, side by side.

The radiance is a lit disc on a dark sky, like a small body in view: inside, a smooth field from 0.2 to 1.0 of
the 10 W m⁻² sr⁻¹ peak (default sensor: about 1000–5000 e, PTRS pixels) with a fine random texture; outside,
zero radiance (dark current only, 0.005 e: inversion pixels). Both streams expose the same image, interleaved,
``--repeats`` times each after one untimed call (numba compiles or loads its cache there; that first call's time is
printed apart); the table gives the median and minimum seconds per exposure and the ratio of the medians.

    .venv/bin/python benchmarks/bench_sensor_noise.py [--sizes 256 1024] [--repeats 15]
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np

from renderlab.sensor.model import SensorOptions, expose


def scene(n: int, seed: int = 0) -> np.ndarray:
    """(n, n) radiance: a textured lit disc of radius 0.4 n on zero radiance."""
    rng = np.random.default_rng(seed)
    y, x = (np.mgrid[:n, :n] + 0.5) / n - 0.5
    r = np.hypot(x, y) / 0.4
    shade = 0.2 + 0.8 * np.clip(1.0 - r, 0.0, 1.0) ** 0.5
    texture = 1.0 + 0.1 * rng.standard_normal((n, n))
    return np.where(r < 1.0, 10.0 * shade * np.clip(texture, 0.5, 1.5), 0.0)


def time_one(radiance: np.ndarray, options: SensorOptions, seed: int) -> float:
    t0 = time.perf_counter()
    expose(radiance, options, np.random.default_rng(seed))
    return time.perf_counter() - t0


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--sizes", type=int, nargs="+", default=[256, 1024])
    p.add_argument("--repeats", type=int, default=15)
    args = p.parse_args(argv)
    streams = {s: dataclasses.replace(SensorOptions(), noise_stream=s) for s in ("per_pixel", "sequential")}
    first = {s: time_one(scene(64), o, 0) for s, o in streams.items()}
    print("first call (64², incl. numba compile or cache load): "
          + ", ".join(f"{s} {t:.3f} s" for s, t in first.items()))
    print(f"{'size':>6} {'per_pixel median (min) s':>26} {'sequential median (min) s':>27} {'ratio':>6}")
    for n in args.sizes:
        radiance = scene(n)
        times = {s: [] for s in streams}
        for k in range(args.repeats):
            for s, o in streams.items():
                times[s].append(time_one(radiance, o, k))
        med = {s: float(np.median(t)) for s, t in times.items()}
        cells = [f"{med[s]:.4f} ({min(times[s]):.4f})" for s in streams]
        print(f"{n:>5}² {cells[0]:>26} {cells[1]:>27} {med['per_pixel'] / med['sequential']:>6.2f}")


if __name__ == "__main__":
    main()
