"""Orbits: Kepler (paper eqs. 10-12 in closed form) and RK4 vs scipy's solve_ivp, conservation, J2 regression."""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

from renderlab.dynamics.orbits import (
    MU_EARTH,
    OrbitElements,
    derivative,
    j2_nodal_rate,
    nadir_attitude,
    propagate,
    raan_of,
    star_tracker_attitude,
)


def _ivp(x0, t, j2=False):
    sol = solve_ivp(lambda _t, x: derivative(x, j2=j2), (0, t[-1]), x0, t_eval=t, method="DOP853", rtol=1e-12,
                    atol=1e-6)
    return sol.y.T


def test_kepler_and_rk4_match_solve_ivp():
    el = OrbitElements(7.2e6, 0.05, np.radians(63), np.radians(40), np.radians(100), np.radians(10))
    t = np.linspace(0, 2 * el.period_s, 41)
    r, v = el.state(t)
    ref = _ivp(np.concatenate([r[0], v[0]]), t)
    assert np.abs(r - ref[:, :3]).max() < 0.05  # metres after two orbits
    assert np.abs(v - ref[:, 3:]).max() < 1e-4
    x = propagate(np.concatenate([r[0], v[0]]), t, max_step_s=2.0)
    assert np.abs(x[:, :3] - ref[:, :3]).max() < 0.5


def test_energy_and_angular_momentum_conserved_many_states():
    rng = np.random.default_rng(3)
    a = 7.0e6 + rng.uniform(0, 1e6, 50)
    r0, v0 = OrbitElements(1, 0).__class__(7e6).state(0.0)
    from renderlab.dynamics.orbits import state_from_elements
    r0, v0 = state_from_elements(a, rng.uniform(0, 0.1, 50), rng.uniform(0, np.pi, 50), rng.uniform(0, 6, 50),
                                 rng.uniform(0, 6, 50), rng.uniform(0, 6, 50))
    x = propagate(np.concatenate([r0, v0], -1), np.array([0.0, 6000.0]), max_step_s=5.0)
    def energy(x):
        return 0.5 * np.sum(x[..., 3:] ** 2, -1) - MU_EARTH / np.linalg.norm(x[..., :3], axis=-1)
    h0, h1 = np.cross(x[0, :, :3], x[0, :, 3:]), np.cross(x[1, :, :3], x[1, :, 3:])
    assert np.max(np.abs(energy(x[1]) / energy(x[0]) - 1)) < 1e-8
    assert np.max(np.linalg.norm(h1 - h0, axis=-1) / np.linalg.norm(h0, axis=-1)) < 1e-8


def test_j2_nodal_regression_matches_analytic_rate():
    el = OrbitElements.circular(1000e3, 45.0)
    t = np.linspace(0, 4 * el.period_s, 5)  # whole orbits: the short-period terms repeat
    r0, v0 = el.state(0.0)
    x = propagate(np.concatenate([r0, v0]), t, j2=True, max_step_s=30.0)  # ≈ 210 RK4 steps per orbit
    raan = np.unwrap(raan_of(x[:, :3], x[:, 3:]))
    rate = np.polyfit(t, raan, 1)[0]
    expect = j2_nodal_rate(el)
    print(f"J2 nodal rate {rate:.4e} rad/s, analytic {expect:.4e}, ratio - 1 = {rate / expect - 1:.2e}")
    assert abs(rate / expect - 1) < 0.01, (rate, expect)  # ≈ -2.6 deg/day at 1000 km, 45 deg


def test_nadir_attitude_and_star_tracker_noise():
    el = OrbitElements.circular(500e3, 90.0)
    r, v = el.state(np.linspace(0, 3000, 7))
    R = nadir_attitude(r, v)
    assert np.allclose(R @ np.array([0, 0, 1.0]), -r / np.linalg.norm(r, axis=1)[:, None])
    assert np.allclose(np.linalg.det(R), 1.0)
    top = -(R @ np.array([0, 1.0, 0]))  # image top
    assert np.all(np.sum(top * v, 1) > 0.99 * np.linalg.norm(v, axis=1))  # circular: v ⟂ r
    sigma = np.radians(10 / 3600)
    Rn = star_tracker_attitude(np.repeat(R[:1], 4000, 0), sigma, np.random.default_rng(0))
    from scipy.spatial.transform import Rotation
    err = Rotation.from_matrix(np.swapaxes(R[:1], 1, 2) @ Rn).as_rotvec()
    assert np.allclose(err.std(0), sigma, rtol=0.06)
