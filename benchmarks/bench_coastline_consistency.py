"""Why is the 1-point / 5 mrad coastline case inconsistent? Three filters on the same runs, side by side.

    .venv/bin/python benchmarks/bench_coastline_consistency.py --runs 200 --revolutions 3

- ``joseph``: the study's EKF (eq. 7 Joseph form, eq. 19 gain);
- ``sqrt``: the array-form QR square-root EKF (:mod:`estimators.coastline.sqrt_ekf`) — same model, a covariance
  that cannot lose symmetry or definiteness; if the inconsistency were numerical, this would remove it;
- ``lkf``: the same filter linearised about the *true* trajectory (STM and H of eqs. 13, 17 at the truth, the
  error state propagated linearly) — the exact linear-Gaussian filter of this problem; if the EKF's
  inconsistency comes from linearising about the estimate (nonlinearity), this one is consistent;
- ``lin-dyn``: dynamics linearised about the truth as in ``lkf``, but the EKF's measurement update (h, H at the
  estimate) — which of the two linearisations matters.
Prints ANEES (6 dof) at 1/3, 2/3 and the end of the span, with the 99 % χ² band, and the seconds of each.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np


def lkf_anees(o, seeds, update_at_estimate: bool = False) -> np.ndarray:
    """ANEES per time of the filter linearised about the truth (same draws as run_batch).

    ``update_at_estimate``: propagate linearly about the truth, but update like the EKF (h and H of eqs. 16-17
    at the estimate) — separates the dynamics' nonlinearity from the measurement's."""
    from estimators.coastline.ekf import BatchCoastlineEKF, EKFOptions, nees
    from estimators.coastline.los import los_jacobian_position, los_predict
    from renderlab.studies.coastline_ekf.geometric import draws_for_runs, measurements, truth_geometry

    geo = truth_geometry(o)
    N, K = len(seeds), len(geo.t_s)
    z_x0, z_los, z_att = draws_for_runs(seeds, K, o.points_per_image)
    sd0 = o.initial_sigmas()
    ekf = BatchCoastlineEKF(np.repeat(geo.x_true[:1], N, 0), np.diag(sd0**2),
                            EKFOptions(sigma_theta_rad=o.sigma_theta_rad, sigma_attitude_rad=o.sigma_star_tracker_rad,
                                       max_step_s=o.filter_step_s))
    dx = z_x0 * sd0                                                  # error state x̂ − x_true
    out = np.empty(K)
    out[0] = nees(dx, ekf.P).mean()
    for k in range(1, K):
        ekf.x = np.repeat(geo.x_true[k - 1:k], N, 0)
        phi = ekf.propagate(geo.t_s[k] - geo.t_s[k - 1])              # STM about the truth
        dx = np.einsum("nij,nj->ni", phi, dx)
        ekf.x = np.repeat(geo.x_true[k:k + 1], N, 0)
        if geo.n_meas[k]:
            y, pts, T_hat = measurements(geo, k, z_los[:, k], z_att[:, k], o.sigma_theta_rad, o.sigma_star_tracker_rad)
            if update_at_estimate:
                ekf.x = geo.x_true[k] + dx
                ekf.update(y, pts, T_hat)
                dx = ekf.x - geo.x_true[k]
                out[k] = nees(dx, ekf.P).mean()
                continue
            _, e_i, rho = los_predict(ekf.x[:, :3], pts, T_hat)
            Hdx = np.einsum("nmij,nj->nmi", los_jacobian_position(e_i, rho, T_hat), dx[:, :3])
            ekf.update(y - Hdx, pts, T_hat)                            # innovation y − h(x_true) − H δx⁻
            dx = dx + (ekf.x - geo.x_true[k])                          # + K ν
        out[k] = nees(dx, ekf.P).mean()
    return out


def main(argv=None) -> int:
    from renderlab.studies.coastline_ekf.scoring import chi2_band
    from renderlab.studies.coastline_ekf.geometric import paper_orbit, run_batch, truth_geometry

    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--orbit", default="i45_h1000")
    p.add_argument("--runs", type=int, default=200)
    p.add_argument("--revolutions", type=float, default=3.0)
    p.add_argument("--points-per-image", type=int, default=1)
    p.add_argument("--sigma-theta-mrad", type=float, default=5.0)
    p.add_argument("--seed", type=int, default=2026)
    a = p.parse_args(argv)
    o = paper_orbit(a.orbit, points_per_image=a.points_per_image, sigma_theta_rad=a.sigma_theta_mrad * 1e-3)
    o = replace(o, duration_s=a.revolutions * o.period_s).validate()
    truth_geometry(o)                                                  # GSHHG + geometry outside the timings
    seeds = np.random.SeedSequence([a.seed, 1]).spawn(a.runs)
    lo, hi = chi2_band(6.0, a.runs)
    print(f"{a.orbit}, {a.runs} runs, {a.revolutions} rev, {a.points_per_image} point(s)/image, σθ {a.sigma_theta_mrad} "
          f"mrad; ANEES 99 % band [{float(lo):.2f}, {float(hi):.2f}]")
    for form in ("joseph", "sqrt", "lkf", "lin-dyn"):
        t0 = time.perf_counter()
        if form in ("lkf", "lin-dyn"):
            an = lkf_anees(o, seeds, update_at_estimate=form == "lin-dyn")
        else:
            tb = run_batch(replace(o, filter_form=form), seeds)["table"]
            t, ne = tb["t_s"].to_numpy(), tb["nees"].to_numpy()
            an = np.array([ne[t == u].mean() for u in np.unique(t)])
        dt = time.perf_counter() - t0
        K = len(an)
        print(f"  {form:6s}: ANEES at 1/3 {an[K // 3]:8.2f}, 2/3 {an[2 * K // 3]:8.2f}, end {an[-1]:8.2f}; "
              f"inside the band {100 * np.mean((an >= lo) & (an <= hi)):5.1f} % of times; {dt:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
