"""Truth dynamics of the unknown-satellite world against independent oracles.

* CW (closed form) vs a full two-body integration of chaser and target (scipy solve_ivp, DOP853),
  expressed in the chaser's LVLH frame: the linearisation error must stay under the second-order
  bound 3·n²·|r|²/a·t² ... and CW must beat a straight-line model by orders of magnitude.
* Euler + gravity gradient (RK4) vs solve_ivp on an independently written inertial-frame form.
* Conservation: |Iω| and kinetic energy torque-free; the Jacobi integral with gravity gradient.
* The estimator's onboard model (estimators.pose.onboard_model, compiled and plain-Python RK4) against
  renderlab.dynamics.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

from estimators.pose.onboard_model import cw_transition, propagate_rotation, propagate_rotation_python
from renderlab.dynamics.attitude import jacobi_integral, propagate_attitude
from renderlab.dynamics.relative_motion import MU_EARTH_M3_S2, R_EARTH_M, cw_propagate, cw_stm, mean_motion

A = R_EARTH_M + 600e3


def _two_body(t, y):
    out = np.empty(12)
    for k in (0, 6):
        r = y[k:k + 3]
        out[k:k + 3] = y[k + 3:k + 6]
        out[k + 3:k + 6] = -MU_EARTH_M3_S2 * r / np.linalg.norm(r) ** 3
    return out


def test_cw_matches_two_body_relative_motion_on_short_arcs():
    n = mean_motion(600e3)
    rel0 = np.array([20.0, -80.0, 15.0, 0.05, -0.3, 0.02])  # LVLH, m and m/s
    # chaser on a circular equatorial orbit; LVLH at t=0: x = r̂, y = v̂, z = ĥ
    rc0, vc0 = np.array([A, 0, 0]), np.array([0, A * n, 0])
    # inertial relative velocity = LVLH velocity + ω × r
    w = np.array([0, 0, n])
    rt0 = rc0 + rel0[:3]
    vt0 = vc0 + rel0[3:] + np.cross(w, rel0[:3])
    times = np.linspace(0, 120.0, 7)
    sol = solve_ivp(_two_body, (0, times[-1]), np.r_[rc0, vc0, rt0, vt0], t_eval=times, rtol=1e-12, atol=1e-9,
                    method="DOP853")
    cw = cw_propagate(rel0, n, times)
    for k, t in enumerate(times):
        rc, rt = sol.y[0:3, k], sol.y[6:9, k]
        x = rc / np.linalg.norm(rc)
        z = np.array([0, 0, 1.0])
        y = np.cross(z, x)
        rel = np.array([x, y, z]) @ (rt - rc)
        err = np.linalg.norm(rel - cw[k, :3])
        rmax = np.linalg.norm(cw[: k + 1, :3], axis=1).max()
        bound = 3 * n**2 * rmax**2 / A * t**2 + 1e-6  # neglected second-order gravity term, integrated twice
        assert err <= bound, (t, err, bound)
        line = rel0[:3] + rel0[3:] * t
        if t >= 60:
            assert np.linalg.norm(rel - line) > 100 * err  # CW captures what a straight line misses


def test_cw_stm_composes_and_matches_onboard_copy():
    n = mean_motion(600e3)
    for t1, t2 in ((10.0, 25.0), (300.0, 1000.0)):
        assert np.allclose(cw_stm(n, t1 + t2), cw_stm(n, t2) @ cw_stm(n, t1), rtol=1e-10, atol=1e-9)
        assert np.allclose(cw_transition(n, t1), cw_stm(n, t1), rtol=1e-12, atol=1e-12)


def _inertial_rhs(I, n):
    """Independent form: state = (R_inertial_from_body flat, ω_body); radial direction rotates in inertia."""
    def f(t, y):
        R = y[:9].reshape(3, 3)
        w = y[9:]
        rhat_i = np.array([np.cos(n * t), np.sin(n * t), 0.0])
        g = R.T @ rhat_i
        torque = 3 * n * n * np.cross(g, I * g)
        wdot = (torque - np.cross(w, I * w)) / I
        Rdot = R @ np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
        return np.r_[Rdot.ravel(), wdot]
    return f


def test_euler_gravity_gradient_matches_solve_ivp():
    # an exaggerated mean motion makes the gravity-gradient torque matter within the arc
    n, I = 0.05, np.array([1.6, 2.1, 2.6])
    q0 = Rotation.from_euler("xyz", [20, -35, 50], degrees=True).as_quat()
    w0 = np.radians([1.5, 3.6, 1.5])
    times = np.linspace(0, 60, 31)
    Q, W = propagate_attitude(q0, w0, I, n, times, substeps=20)
    # LVLH→inertial at t: rotation about z by n t, so R_i_from_b = Rz(nt) R_lvlh_from_b
    R0 = Rotation.from_quat(q0).as_matrix()
    sol = solve_ivp(_inertial_rhs(I, n), (0, 60), np.r_[R0.ravel(), w0], t_eval=times, rtol=1e-11, atol=1e-12,
                    method="DOP853")
    for k, t in enumerate(times):
        R_i = sol.y[:9, k].reshape(3, 3)
        R_lvlh = Rotation.from_euler("z", -n * t).as_matrix() @ R_i
        ang = Rotation.from_matrix(R_lvlh @ Rotation.from_quat(Q[k]).as_matrix().T).magnitude()
        assert ang < 1e-7, (t, ang)
        assert np.allclose(W[k], sol.y[9:, k], atol=1e-9)
    # the onboard copy (matrix RK4, 4 substeps; compiled and plain-Python) agrees with the truth model
    Rb, Wb = propagate_rotation(R0, w0, I, n, times, substeps=4)
    Rp, Wp = propagate_rotation_python(R0, w0, I, n, times, substeps=4)
    for k in range(len(times)):
        ang = Rotation.from_matrix(Rb[k] @ Rotation.from_quat(Q[k]).as_matrix().T).magnitude()
        assert ang < 1e-6 and np.allclose(Wb[k], W[k], atol=1e-7)
        assert np.allclose(Rb[k], Rp[k], atol=1e-9) and np.allclose(Wb[k], Wp[k], atol=1e-12)


def test_attitude_conservation_laws_and_inertia_scale_invariance():
    I = np.array([1.6, 2.1, 2.6])
    q0 = Rotation.from_euler("xyz", [10, 70, -30], degrees=True).as_quat()
    w0 = np.radians([3.0, -2.0, 4.0])
    times = np.linspace(0, 100, 51)
    Q, W = propagate_attitude(q0, w0, I, 0.0, times)
    h = np.linalg.norm(I * W, axis=1)
    T = 0.5 * np.sum(I * W * W, axis=1)
    assert np.ptp(h) / h[0] < 1e-10 and np.ptp(T) / T[0] < 1e-10
    assert np.ptp(W[:, 0]) > 1e-3  # the motion is not trivial (a test that can fail)
    n = 0.02
    Q, W = propagate_attitude(q0, w0, I, n, times)
    J = np.array([jacobi_integral(q, w, I, n) for q, w in zip(Q, W)])
    assert np.ptp(J) / abs(J[0]) < 1e-9
    Q5, W5 = propagate_attitude(q0, w0, 5 * I, n, times)  # I → 5I: same motion (ratios only)
    assert np.allclose(Q5, Q, atol=1e-12) and np.allclose(W5, W, atol=1e-12)
