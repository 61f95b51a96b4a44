"""Descent navigation speed: the descent EKF's steps, and one closed-loop descent run per landmark method, as a
ratio to real time at the paper's 3 Hz (Wright et al.: 1 MP frames at 3 Hz, a 333 ms budget per image).

Usage (the truth set of a descent campaign, e.g. the truth cache of ``results/descent_navigation``'s campaign)::

    .venv/bin/python benchmarks/bench_descent_navigation.py TRUTHSET [--scenario results/descent_navigation/scenario.toml]
        [--images 5] [--repeats 200]

(a) Filter: ``set_input + propagate`` over one 1-s accelerometer sample and ``update`` with k = 8 landmark pixels
(the study's cap), median and minimum of ``--repeats`` interleaved calls, for each map-state mode side by side
(``off``: the filter without map states; ``estimate`` / ``consider``: 8 landmarks' map errors, 30 states).
(b) Closed loop: one run of every method of the scenario on the first ``--images`` images of the truth set (the
study's own loop, :func:`renderlab.studies.descent_navigation.loop.run_method`, fresh filter), wall time per image
split into landmark measurement and everything else (filter, selection, bookkeeping).
(c) 1 MP extrapolation, measured: at the same field of view a 1024² image has 4× the pixels per metre, so the
study's landmark selection (GSD ratio near 1) gives templates of the same pixel size while the search distance in
pixels grows 4×. Each method is therefore timed again on the same images and landmarks with every search distance
forced to 4× (min = max = 4 r, r the distance the filter's covariance gives, ≤ 128 px): its time per image is the
1 MP estimate. The image-level work that scales with the whole image (reading and masking it) is not included.
Ratio to real time = time per image / 333 ms (< 1: faster than real time).
"""

from __future__ import annotations

import os

# the onboard filter is single-threaded; OpenBLAS's threads on a 16-row solve cost ~100x on a loaded machine
# (measured here: update median 90 ms with the default threads at load 19, 0.33 ms with one)
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

BUDGET_MS = 1000.0 / 3.0


def filter_steps(repeats: int) -> None:
    """(a) per map-state mode (off = the filter before map states; estimate; consider; estimate with the iterated
    update of 3 iterations), interleaved call by call:
    propagate 1 s, the first update with 8 new landmarks (augmentation: 6 → 30 states), then propagate 1 s and
    update again with the same 8 (30 states, the steady state of the descent)."""
    from estimators.descent_nav import DescentEKF, DescentNavOptions, pixel_covariance
    from renderlab.geometry.camera import CameraModel
    from renderlab.geometry.rotations import look_at

    cam = CameraModel.from_dict({"width": 256, "height": 256, "fx": 1218.0, "fy": 1218.0, "cx": 127.5, "cy": 127.5})
    rng = np.random.default_rng(0)
    ground = np.array([230.0, 80.0, 60.0])
    up = ground / np.linalg.norm(ground)
    pts = ground + rng.normal(0, 5.0, (8, 3))
    r = ground + 120 * up
    R = look_at(r, ground, np.array([0.0, 0.0, 1.0])).as_matrix()
    modes = ("off", "estimate", "consider", "estimate, 3 iterations")
    filters = {m: DescentEKF(DescentNavOptions(gm_m3_s2=2.9, omega_rad_s=(0, 0, 4.7e-4), q_acc_m2_s3=1e-10,
                                               sigma_input_mps2=2e-5, map_states=m.split(",")[0],
                                               iterations=3 if "iterations" in m else 1)) for m in modes}
    z = cam.project((pts - r) @ R).reshape(-1)
    ctx = {"points_body_m": pts, "R_body_from_cam": R, "camera": cam, "landmark_ids": np.arange(8),
           "landmark_cov_m2": np.repeat((np.eye(3) * 0.01**2)[None], 8, 0)}
    Rm = pixel_covariance(cam, pts, r, R, 0.3, 5e-5)
    t = {m: {"prop": [], "first": [], "steady": []} for m in modes}
    for i in range(repeats):
        for m in modes:
            f = filters[m]
            f.initialize(0.0, np.r_[r, 0, 0, 0], np.eye(6))
            t0 = time.perf_counter()
            f.set_input(np.zeros(3))
            f.propagate(1.0)
            t1 = time.perf_counter()
            f.update(1.0, "pixel", z, Rm, ctx)
            t2 = time.perf_counter()
            f.propagate(2.0)
            t3 = time.perf_counter()
            f.update(2.0, "pixel", z, Rm, ctx)
            t4 = time.perf_counter()
            t[m]["prop"].append((t1 - t0) * 1e3)
            t[m]["first"].append((t2 - t1) * 1e3)
            t[m]["steady"].append((t4 - t3) * 1e3)
    med = {m: {k: statistics.median(v) for k, v in d.items()} for m, d in t.items()}
    for m in modes:
        d = t[m]
        print(f"(a) filter map_states={m:22s} ({6 + (24 if m != 'off' else 0)} states after the first update): "
              f"propagate 1 s median {med[m]['prop']:.3f} ms (min {min(d['prop']):.3f}); update k = 8, first "
              f"median {med[m]['first']:.3f} ms (min {min(d['first']):.3f}), steady median {med[m]['steady']:.3f} ms "
              f"(min {min(d['steady']):.3f}) ({repeats} interleaved calls)")
    for m in modes[1:]:
        print(f"(a) ratio {m} / off (medians): propagate {med[m]['prop'] / med['off']['prop']:.2f}x, first update "
              f"{med[m]['first'] / med['off']['first']:.2f}x, steady update {med[m]['steady'] / med['off']['steady']:.2f}x")


class _Scaled:
    """A method wrapper that forces every search distance to ``scale`` × the given one (≤ 128 px)."""

    def __init__(self, impl, scale: int):
        self.impl, self.scale, self.name = impl, scale, impl.name

    def measure_frame(self, frame):
        r = np.minimum(np.asarray(frame.search_px) * self.scale, 128).astype(int)
        return self.impl.measure_frame(replace(frame, search_px=r))


def closed_loop(ts_dir: Path, scenario: Path, images: int) -> None:
    from renderlab.campaign.reexpose import ReexposedTruthSet
    from renderlab.files.truthset import TruthSet
    from renderlab.measurement.descent_filter import DescentNavFilter
    from renderlab.measurement.runner import MeasureOptions, make_method, onboard_photometry
    from renderlab.scenario import load_scenario
    from renderlab.sensor.model import SensorOptions
    from renderlab.studies.descent_navigation import loop
    from renderlab.studies.descent_navigation.run import filter_options, run_inputs, section
    from renderlab.studies.descent_navigation.truth import true_descent
    from renderlab.worlds.ev5.catalog import read_catalog

    sc, _ = load_scenario(scenario)
    cfg = section(sc)
    ts0 = TruthSet.open(ts_dir)
    ss = np.random.SeedSequence(1).spawn(4)
    ts = ReexposedTruthSet(ts0, SensorOptions(**sc.sensor.options_dict()),
                           [int(s.generate_state(1)[0]) for s in ss[0].spawn(len(ts0))], cache=True)
    truth = true_descent(ts0, sc, cfg)
    inp = run_inputs(ts, truth, read_catalog(ts_dir), cfg, sc, 0, tuple(ss[1:]))
    keep = slice(0, images)
    inp.times, inp.R_true, inp.R_star = inp.times[keep], inp.R_true[keep], inp.R_star[keep]
    for i in range(images):
        ts.load(i)                                         # re-exposure outside the timing
    mopts = MeasureOptions(n_sigma=cfg.n_sigma, min_search_px=cfg.min_search_px, max_search_px=cfg.max_search_px)
    L_table, _ = onboard_photometry(ts0, mopts)
    wide = replace(mopts, max_search_px=128)
    for name in cfg.methods:
        impl = make_method(name, mopts, L_table)
        warm = replace(inp, times=inp.times[:1])              # JIT compilation and caches outside the timing
        loop.run_method(impl, warm, DescentNavFilter(filter_options(cfg, truth.omega_rad_s)), cfg, mopts)
        out = {}
        for label, m, o in (("256^2", impl, mopts), ("1 MP search (4x)", _Scaled(impl, 4), wide)):
            t0 = time.perf_counter()
            frows, lrows = loop.run_method(m, inp, DescentNavFilter(filter_options(cfg, truth.omega_rad_s)), cfg, o)
            wall = (time.perf_counter() - t0) * 1e3 / images
            meas = sum(r["t_ms"] for r in lrows) / images
            out[label] = (wall, meas, np.mean([r["search_px"] for r in lrows]), len(lrows) / images)
        for label, (wall, meas, spx, n) in out.items():
            print(f"(b/c) {name:13s} {label:17s}: {wall:8.1f} ms/image (landmarks {meas:8.1f} ms, rest "
                  f"{wall - meas:6.1f} ms; {n:.1f} landmarks/image, mean search {spx:.1f} px) -> "
                  f"{wall / BUDGET_MS:6.2f} x real time at 3 Hz")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("truthset", type=Path)
    ap.add_argument("--scenario", type=Path, default=Path("results/descent_navigation/scenario.toml"))
    ap.add_argument("--images", type=int, default=5)
    ap.add_argument("--repeats", type=int, default=200)
    a = ap.parse_args()
    print(f"# {' '.join(sys.argv)}\n# {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"load {os.getloadavg()[0]:.1f}")
    filter_steps(a.repeats)
    closed_loop(a.truthset, a.scenario, a.images)


if __name__ == "__main__":
    main()
