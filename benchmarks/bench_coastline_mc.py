"""Geometric coastline-EKF Monte Carlo: the vectorised batch filter vs per-run loops, timed in one process.

    .venv/bin/python benchmarks/bench_coastline_mc.py                      # 1000 runs, i90_h1000, one orbit
    .venv/bin/python benchmarks/bench_coastline_mc.py --runs 100 --loop-runs 10   # smoke test

Times, on the same truth, seeds, draws and measurements:

(a) ``run_batch``: all runs at once (``BatchCoastlineEKF``, numpy, leading run axis), including the measurement
    generation, the per-run draws and the output table — the whole study function;
(b) a per-run loop over FilterPy 1.4.5's ``ExtendedKalmanFilter`` (``filterpy`` is a benchmark-only dependency):
    ``F`` = the same RK4 STM, ``predict_x`` = the same RK4 state propagation, ``update`` with the stacked eq. 17 H
    and R + σθ²·blkdiag(eeᵀ) — eq. 19's modification, which FilterPy needs because it inverts S (K is unchanged and
    so is the Joseph covariance because K e = 0);
(c) a per-run loop over this repository's filter with N = 1 (separates the gain of batching from FilterPy's cost).

Loops (b) and (c) run ``--loop-runs`` runs and are extrapolated linearly to ``--runs`` (marked EXTRAPOLATED
unless all runs are looped). A sanity line prints the largest difference of the final estimates (b, c vs a).
The one-time truth (GSHHG load, orbit, visibility) is timed separately; it is shared by all runs.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def _filterpy_loop(o, geo, z_x0, z_los, z_att, n):
    from filterpy.kalman import ExtendedKalmanFilter

    from estimators.coastline.dynamics import propagate_state_stm
    from estimators.coastline.los import los_jacobian_position, los_predict
    from renderlab.studies.coastline_ekf.geometric import measurements

    sd0 = np.array([o.sigma_r0_m] * 3 + [o.sigma_v0_mps] * 3)
    s2 = o.sigma_theta_rad**2
    finals = []
    for j in range(n):
        f = ExtendedKalmanFilter(dim_x=6, dim_z=3)
        f.x = (geo.x_true[0] + z_x0[j] * sd0)[:, None]
        f.P = np.diag(sd0**2)
        f.Q = np.zeros((6, 6))
        for k in range(1, len(geo.t_s)):
            xn, phi = propagate_state_stm(f.x.T, geo.t_s[k] - geo.t_s[k - 1], max_step_s=o.filter_step_s)
            f.F = phi[0]
            f.predict_x = lambda u=0, xn=xn: setattr(f, "x", xn[0][:, None])
            f.predict()
            if geo.n_meas[k]:
                y, pts, T_hat = measurements(geo, k, z_los[j:j + 1, k], z_att[j:j + 1, k], o.sigma_theta_rad,
                                             o.sigma_star_tracker_rad)
                m = len(pts)

                def hx(x, pts=pts, T=T_hat[0]):
                    return los_predict(x[:3].T, pts, T)[0].reshape(3 * m, 1)

                def hjac(x, pts=pts, T=T_hat[0]):
                    _, e_i, rho = los_predict(x[:3].T, pts, T)
                    H = np.zeros((3 * m, 6))
                    H[:, :3] = los_jacobian_position(e_i, rho, T).reshape(3 * m, 3)
                    return H

                e = hx(f.x).reshape(m, 3)
                R = np.zeros((3 * m, 3 * m))
                G = np.zeros((3 * m, 3))
                for i in range(m):
                    R[3 * i:3 * i + 3, 3 * i:3 * i + 3] = s2 * np.eye(3)      # σθ²(I − eeᵀ) + ν eeᵀ, ν = σθ²
                    G[3 * i:3 * i + 3] = np.cross(np.eye(3), e[i])
                R += o.sigma_star_tracker_rad**2 * G @ G.T
                f.update(y[0].reshape(3 * m, 1), hjac, hx, R=R)
        finals.append(f.x[:, 0].copy())
    return np.array(finals)


def _own_loop(o, geo, z_x0, z_los, z_att, n):
    from estimators.coastline.ekf import BatchCoastlineEKF, EKFOptions
    from renderlab.studies.coastline_ekf.geometric import measurements

    sd0 = np.array([o.sigma_r0_m] * 3 + [o.sigma_v0_mps] * 3)
    opts = EKFOptions(sigma_theta_rad=o.sigma_theta_rad, sigma_attitude_rad=o.sigma_star_tracker_rad,
                      max_step_s=o.filter_step_s)
    finals = []
    for j in range(n):
        f = BatchCoastlineEKF(geo.x_true[0] + z_x0[j:j + 1] * sd0, np.diag(sd0**2), opts)
        for k in range(1, len(geo.t_s)):
            f.propagate(geo.t_s[k] - geo.t_s[k - 1])
            if geo.n_meas[k]:
                f.update(*measurements(geo, k, z_los[j:j + 1, k], z_att[j:j + 1, k], o.sigma_theta_rad,
                                       o.sigma_star_tracker_rad))
        finals.append(f.x[0].copy())
    return np.array(finals)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--runs", type=int, default=1000)
    p.add_argument("--loop-runs", type=int, default=50, help="runs timed in the per-run loops (then extrapolated)")
    p.add_argument("--orbit", default="i90_h1000")
    p.add_argument("--repeats", type=int, default=2, help="repeats of the vectorised batch (median, min)")
    p.add_argument("--seed", type=int, default=2026)
    a = p.parse_args(argv)

    from renderlab.studies.coastline_ekf.geometric import draws_for_runs, paper_orbit, run_batch, truth_geometry

    print(f"command: {' '.join(sys.argv)}")
    print(f"cpu: {platform.processor() or platform.machine()}, cores: {os.cpu_count()}, "
          f"load average: {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f}")
    o = paper_orbit(a.orbit)
    t0 = time.perf_counter()
    geo = truth_geometry(o)
    t_geo = time.perf_counter() - t0
    K = len(geo.t_s)
    print(f"orbit {a.orbit}: {K - 1} images every {o.cadence_s:.0f} s over one {o.period_s / 60:.1f}-min orbit, "
          f"{int((geo.n_meas > 0).sum())} with coastline, {int(geo.n_meas.sum())} LOS in all")
    print(f"one-time truth (GSHHG load + orbit + visibility): {t_geo:.1f} s")
    seeds = np.random.SeedSequence(a.seed).spawn(a.runs)
    times, out = [], None
    for _ in range(a.repeats):
        t0 = time.perf_counter()
        out = run_batch(o, seeds, keep_history=True)
        times.append(time.perf_counter() - t0)
    t_vec = float(np.median(times))
    z_x0, z_los, z_att = draws_for_runs(seeds[:a.loop_runs], K, o.points_per_image)
    n = min(a.loop_runs, a.runs)
    t0 = time.perf_counter()
    x_fp = _filterpy_loop(o, geo, z_x0, z_los, z_att, n)
    t_fp = (time.perf_counter() - t0) * a.runs / n
    t0 = time.perf_counter()
    x_own = _own_loop(o, geo, z_x0, z_los, z_att, n)
    t_own = (time.perf_counter() - t0) * a.runs / n
    tag = "" if n == a.runs else f"  EXTRAPOLATED from {n} runs"
    print(f"\n{'configuration':48s} {'s for ' + str(a.runs) + ' runs':>16s}")
    print(f"{'(a) vectorised run_batch (median of ' + str(a.repeats) + ')':48s} {t_vec:16.2f}   min {min(times):.2f}")
    print(f"{'(b) per-run FilterPy 1.4.5 EKF loop':48s} {t_fp:16.2f}{tag}")
    print(f"{'(c) per-run loop, this filter with N = 1':48s} {t_own:16.2f}{tag}")
    print(f"\nratio FilterPy loop / vectorised: {t_fp / t_vec:.1f}x;  own N=1 loop / vectorised: {t_own / t_vec:.1f}x")
    print(f"issue target: 1000 runs one orbit <= 60 s -> vectorised {t_vec:.1f} s "
          f"({'met' if t_vec <= 60 else 'NOT met'}; + {t_geo:.1f} s one-time truth)")
    x_vec = out["x_hat"][:n, -1]
    print(f"sanity: max |final estimate difference| FilterPy vs vectorised {np.abs(x_fp - x_vec)[:, :3].max():.2e} m, "
          f"{np.abs(x_fp - x_vec)[:, 3:].max():.2e} m/s; own loop vs vectorised {np.abs(x_own - x_vec).max():.2e}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
