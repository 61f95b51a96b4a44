"""Stage 1 of the unknown-satellite estimator: seconds per solve, old vs new Jacobian, side by side.

    .venv/bin/python benchmarks/bench_pose_stage1.py [--frames 25] [--dt 1.0] [--repeat 3]

One synthetic problem (6 points, CW + Euler/gravity-gradient truth from renderlab.dynamics, σ = 0.3 px,
seeded errors of the a-priori), solved from the same start with the same solver (scipy least_squares,
"lm", same tolerances and evaluation budget) and three Jacobians:

* ``fd+python``: the previous implementation — finite differences (point columns grouped), each
  evaluation propagating eq. 2 with the plain-Python RK4;
* ``fd+numba``: the same finite differences over the compiled propagator;
* ``analytic+numba``: the variational equations (one compiled propagation per Jacobian).

Prints seconds per Jacobian, per solve, the evaluation counts and the final cost (all three must reach
the same minimum), and the ratios to the old configuration.
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # tiny matrices: threads only add contention

import numpy as np  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402


def problem(frames: int, dt: float, seed: int, jacobian: str, integrator: str):
    from estimators.pose import Stage1Options, Stage1Problem, TrackOptions, build_database, track_points
    from estimators.pose.onboard_model import exp_so3
    from renderlab.dynamics.attitude import propagate_attitude
    from renderlab.dynamics.relative_motion import cw_propagate, mean_motion
    from renderlab.geometry.camera import CameraModel
    from renderlab.geometry.rotations import look_at

    cam = CameraModel.from_dict({"width": 640, "height": 480, "fx": 554.0, "fy": 554.0, "cx": 319.5, "cy": 239.5})
    pts = np.array([[0.8, 0.2, 0.5], [-0.6, 0.7, -0.4], [0.1, -0.9, 0.6], [-0.5, -0.4, -0.7], [0.7, -0.5, -0.3],
                    [-0.2, 0.6, 0.8]])
    n = mean_motion(600e3)
    times = np.arange(frames) * dt
    rv = cw_propagate([0.05, -4.6, 0.05, 0.01, -0.12, 0.005], n, times)
    inertia = np.array([1.6, 2.1, 2.6])
    Q, W = propagate_attitude(np.array([0.2, -0.1, 0.3, 0.93]) / np.linalg.norm([0.2, -0.1, 0.3, 0.93]),
                              np.radians([1.5, 3.6, 1.5]), inertia, n, times)
    d = np.array([0.0, -0.6, 0.0])
    R_lc = look_at(d, d + [0, -1, 0], [1, 0, 0]).as_matrix()
    Rs = Rotation.from_quat(Q).as_matrix()
    rng = np.random.default_rng(seed)
    det = [cam.project((rv[k, :3] + pts @ Rs[k].T - d) @ R_lc) + rng.normal(0, 0.3, (len(pts), 2))
           for k in range(frames)]
    db = build_database(track_points(det, TrackOptions(15.0, 5)), TrackOptions(15.0, 5))
    R_ref = Rs[0] @ exp_so3(rng.normal(0, np.radians(3), 3))
    prob = Stage1Problem(cam, R_lc, d, n, times, db, R_ref, float(np.linalg.norm(rv[0, :3] - d)),
                         Stage1Options(sigma_px=0.3, range_prior_sigma_m=0.02, jacobian=jacobian,
                                       integrator=integrator))
    start = (rv[0, :3] + rng.normal(0, 0.03, 3), rv[0, 3:] + rng.normal(0, 0.01, 3),
             W[0] + rng.normal(0, np.radians(0.3), 3), inertia[:2] / inertia[2] * (1 + rng.normal(0, 0.05, 2)))
    return prob, start


def main() -> None:
    from estimators.pose import solve_stage1

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=25)
    ap.add_argument("--dt", type=float, default=1.0)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--seed", type=int, default=3)
    args = ap.parse_args()
    rows = []
    for jac, integ in (("fd", "python"), ("fd", "numba"), ("analytic", "numba")):
        prob, start = problem(args.frames, args.dt, args.seed, jac, integ)
        solve_stage1(prob, *start)  # warm-up (numba compilation, caches)
        t_jac, t_solve = [], []
        for _ in range(args.repeat):
            th0 = np.r_[start[0], start[1], np.zeros(3), start[2], np.log(start[3]),
                        prob.initial_points(np.r_[start[0], start[1], np.zeros(3), start[2],
                                                  np.log(start[3])]).ravel()]
            t = time.perf_counter()
            prob.jacobian(th0)
            t_jac.append(time.perf_counter() - t)
            res = solve_stage1(prob, *start)
            t_solve.append(res.seconds)
        rows.append((f"{jac}+{integ}", min(t_jac), min(t_solve), res))
    base_j, base_s = rows[0][1], rows[0][2]
    print(f"stage-1 problem: {args.frames} frames, dt {args.dt} s, {prob.db.n_points} points, "
          f"{len(prob.db.frame)} measurements, {len(rows[0][3].theta)} parameters; best of {args.repeat}")
    print(f"{'jacobian':16s} {'s/jacobian':>11s} {'s/solve':>9s} {'nfev':>5s} {'njev':>5s} {'status':>6s} "
          f"{'cost':>10s} {'jac speed-up':>12s} {'solve speed-up':>14s}")
    for name, tj, ts, res in rows:
        print(f"{name:16s} {tj:11.5f} {ts:9.3f} {res.nfev:5d} {res.njev:5d} {res.status:6d} {res.cost:10.3f} "
              f"{base_j / tj:12.1f} {base_s / ts:14.1f}")


if __name__ == "__main__":
    main()
