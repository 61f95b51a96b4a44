"""Basilisk's ``relativeODuKF`` behind the lab's navigation-filter contract (``renderlab.basilisk.od_filter``).

The linear-Gaussian case: truth is the filter's own model — two-body motion about Mars with Basilisk's μ, integrated
independently by scipy's DOP853 at 1e-12 relative tolerance — position measurements are the truth plus exactly the
declared Gaussian noise, the initial estimate is the truth plus a draw from P0. A consistent filter's NEES at each
step, averaged over independent runs, lies in the two-sided χ² band of 6·N dof (per step, over runs: not one run's
time average); a filter told a 4× too small R must leave it.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("Basilisk")

from renderlab.basilisk.od_filter import ODuKFOptions, RelativeODuKF  # noqa: E402
from renderlab.contracts.navigation import FilterMeasurement, NavigationFilter  # noqa: E402
from renderlab.errors import UserError  # noqa: E402

MU_MARS = 42828.314e9  # m³/s², Basilisk's astroConstants MU_MARS (42828.314 km³/s²)


def _truth(ts):
    from scipy.integrate import solve_ivp

    r0 = 1.0e7
    v = np.sqrt(MU_MARS / r0)
    x0 = np.array([r0, 0.0, 0.0, 0.0, v * np.cos(0.6), v * np.sin(0.6)])
    sol = solve_ivp(lambda t, x: np.concatenate([x[3:], -MU_MARS * x[:3] / np.linalg.norm(x[:3]) ** 3]),
                    (0.0, ts[-1]), x0, t_eval=ts, rtol=1e-12, atol=1e-6, method="DOP853")
    return sol.y.T


def _run(n_runs: int, declared_scale: float, seed: int = 1):
    ts = np.arange(0, 11) * 60.0
    X = _truth(ts)
    P0 = np.diag([5e3**2] * 3 + [5.0**2] * 3)
    R = np.diag([2e3**2, 1e3**2, 3e3**2])
    rng = np.random.default_rng(seed)
    nees, nis = np.zeros((n_runs, len(ts))), np.zeros((n_runs, len(ts) - 1))
    for k in range(n_runs):
        f = RelativeODuKF()
        x0 = X[0] + rng.multivariate_normal(np.zeros(6), P0)
        f.initialize(0.0, x0, P0)
        for j in range(1, len(ts)):
            z = X[j, :3] + rng.multivariate_normal(np.zeros(3), R)
            m = FilterMeasurement("position", z, R * declared_scale)
            zc = m.z.copy()
            u = f.update(ts[j], m)
            assert np.array_equal(m.z, zc) and u.dof == 3
            nis[k, j - 1] = u.nis
            e = f.x - X[j]
            nees[k, j] = e @ np.linalg.solve(f.P, e)
        e = x0 - X[0]
        nees[k, 0] = e @ np.linalg.solve(P0, e)
    return nees, nis


def _band(dof: int, n: int):
    from scipy.stats import chi2

    return chi2.ppf(0.025, dof * n) / n, chi2.ppf(0.975, dof * n) / n


def test_relative_od_ukf_is_consistent_on_the_linear_gaussian_case():
    n = 60
    nees, nis = _run(n, 1.0)
    lo, hi = _band(6, n)
    anees = nees[:, 1:].mean(axis=0)                      # per step over independent runs
    assert np.mean((anees >= lo) & (anees <= hi)) >= 0.8, (anees, lo, hi)
    lo3, hi3 = _band(3, n)
    anis = nis.mean(axis=0)
    assert np.mean((anis >= lo3) & (anis <= hi3)) >= 0.8, (anis, lo3, hi3)


def test_an_overconfident_measurement_model_fails_the_same_check():
    n = 60
    nees, _ = _run(n, 0.25)                               # the filter is told R/4
    _, hi = _band(6, n)
    assert np.all(nees[:, 2:].mean(axis=0) > hi)


def test_contract_and_refusals():
    f = RelativeODuKF(ODuKFOptions())
    assert isinstance(f, NavigationFilter)
    with pytest.raises(UserError, match="initialize"):
        f.propagate(10.0)
    X = _truth(np.array([0.0, 600.0]))
    P0 = np.diag([1e6] * 3 + [1.0] * 3)
    f.initialize(0.0, X[0], P0)
    with pytest.raises(UserError, match="position"):
        f.update(60.0, FilterMeasurement("los", np.zeros(2), np.eye(2)))
    f.propagate(600.0)     # one RK4 step per time update, whatever its length: 2.5 m off after 600 s (measured)
    assert np.linalg.norm(f.x[:3] - X[1, :3]) < 10.0
    with pytest.raises(UserError, match="backwards"):
        f.propagate(300.0)
