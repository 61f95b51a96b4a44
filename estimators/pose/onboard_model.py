r"""The onboard motion and measurement model of the two-stage method (Ivanov et al. 2018, eqs. 1-4).

Re-implemented here on purpose (an onboard estimator carries its own model; the lab's truth
dynamics in ``renderlab.dynamics`` are its test oracle):

* eq. 1, Clohessy-Wiltshire: closed-form transition of the target's centre of mass relative to the
  chaser in the orbital (LVLH) frame — x radial, z orbit normal, y = z × x;
* eq. 2, Euler's equations with gravity-gradient torque for principal moments ``I``; the attitude is
  ``R_lvlh_from_body`` (the transpose of the paper's A) integrated as a rotation matrix with RK4 in
  plain floats (re-orthonormalised each step); ω is the absolute body rate;
* eqs. 3-4, measurement: a reference point ``p`` (body) is seen by the camera at
  ``ρ = R_lvlh_from_camᵀ (r + R_lvlh_from_body p − d)`` and projected by the camera model.

Only ratios of ``I`` enter eq. 2 (``I → cI`` leaves it unchanged).
"""

from __future__ import annotations

import math

import numpy as np


def cw_transition(n: float, t: float) -> np.ndarray:
    """6×6 closed-form CW transition (eq. 1) for state [x, y, z, ẋ, ẏ, ż]."""
    s, c, nt = math.sin(n * t), math.cos(n * t), n * t
    return np.array([
        [4 - 3 * c, 0, 0, s / n, 2 * (1 - c) / n, 0],
        [6 * (s - nt), 1, 0, 2 * (c - 1) / n, 4 * s / n - 3 * t, 0],
        [0, 0, c, 0, 0, s / n],
        [3 * n * s, 0, 0, c, 2 * s, 0],
        [6 * n * (c - 1), 0, 0, -2 * s, 4 * c - 3, 0],
        [0, 0, -n * s, 0, 0, c],
    ])


def _rhs(R, w, I, n):
    """dR/dt (3×3 nested lists) and dω/dt for R = R_lvlh_from_body, ω absolute (body)."""
    g = R[0]          # Rᵀ x̂ = first row of R
    b = R[2]          # Rᵀ ẑ
    I1, I2, I3 = I
    w1, w2, w3 = w
    k = 3.0 * n * n
    Ig = (I1 * g[0], I2 * g[1], I3 * g[2])
    t1 = k * (g[1] * Ig[2] - g[2] * Ig[1])
    t2 = k * (g[2] * Ig[0] - g[0] * Ig[2])
    t3 = k * (g[0] * Ig[1] - g[1] * Ig[0])
    dw = ((t1 - (I3 - I2) * w2 * w3) / I1, (t2 - (I1 - I3) * w3 * w1) / I2, (t3 - (I2 - I1) * w1 * w2) / I3)
    r1, r2, r3 = w1 - n * b[0], w2 - n * b[1], w3 - n * b[2]   # rate relative to LVLH (body)
    # dR/dt = R [ω_rel]×
    dR = [[row[1] * r3 - row[2] * r2, row[2] * r1 - row[0] * r3, row[0] * r2 - row[1] * r1] for row in R]
    return dR, dw


def _axpy(R, dR, h):
    return [[R[i][j] + h * dR[i][j] for j in range(3)] for i in range(3)]


def _orthonormalise(R):
    a = np.asarray(R)
    if not np.all(np.isfinite(a)):
        raise ValueError("attitude integration diverged")
    u, _, vt = np.linalg.svd(a)
    return (u @ vt).tolist()


def propagate_rotation(R0: np.ndarray, w0, inertia, n: float, times, substeps: int = 4):
    """R_lvlh_from_body (N, 3, 3) and ω (N, 3) at ``times`` (times[0] = epoch of R0, ω0), RK4 (eq. 2).

    The compiled kernel of :mod:`.variational` (no sensitivities); same RK4 steps as
    :func:`propagate_rotation_python`, the plain-Python version kept as the benchmark baseline.
    """
    from .variational import propagate

    R, W, _, _ = propagate(R0, w0, np.log(np.asarray(inertia, float)), n, times, substeps)
    return R, W


def propagate_rotation_python(R0: np.ndarray, w0, inertia, n: float, times, substeps: int = 4):
    """Plain-Python RK4 of eq. 2 (re-orthonormalised each output step): the pre-numba baseline."""
    R = np.asarray(R0, float).tolist()
    w = tuple(float(v) for v in w0)
    I = tuple(float(v) for v in inertia)
    times = np.asarray(times, float)
    Rs, Ws = [np.array(R)], [np.array(w)]
    for t0, t1 in zip(times[:-1], times[1:]):
        h = (t1 - t0) / substeps
        for _ in range(substeps):
            k1R, k1w = _rhs(R, w, I, n)
            k2R, k2w = _rhs(_axpy(R, k1R, h / 2), tuple(a + h / 2 * b for a, b in zip(w, k1w)), I, n)
            k3R, k3w = _rhs(_axpy(R, k2R, h / 2), tuple(a + h / 2 * b for a, b in zip(w, k2w)), I, n)
            k4R, k4w = _rhs(_axpy(R, k3R, h), tuple(a + h * b for a, b in zip(w, k3w)), I, n)
            R = [[R[i][j] + h / 6 * (k1R[i][j] + 2 * k2R[i][j] + 2 * k3R[i][j] + k4R[i][j]) for j in range(3)]
                 for i in range(3)]
            w = tuple(a + h / 6 * (p + 2 * q + 2 * r + s) for a, p, q, r, s in zip(w, k1w, k2w, k3w, k4w))
        R = _orthonormalise(R)
        Rs.append(np.array(R))
        Ws.append(np.array(w))
    return np.array(Rs), np.array(Ws)


def predict_pixels(camera, R_lvlh_from_cam, d_lvlh, r_lvlh, R_lvlh_from_body, points_body) -> np.ndarray:
    """Pixel (s, l) of body points (M, 3) for one pose (eqs. 3-4); NaN behind the camera."""
    p_lvlh = r_lvlh + points_body @ R_lvlh_from_body.T
    rho = (p_lvlh - d_lvlh) @ R_lvlh_from_cam
    return camera.project(rho)


def exp_so3(v) -> np.ndarray:
    """Rotation matrix exp([v]×) (Rodrigues)."""
    v = np.asarray(v, float)
    th = float(np.linalg.norm(v))
    K = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    if th < 1e-12:
        return np.eye(3) + K
    return np.eye(3) + math.sin(th) / th * K + (1 - math.cos(th)) / th**2 * K @ K


def log_so3(R) -> np.ndarray:
    """Rotation vector of R (inverse of :func:`exp_so3`, angle < π)."""
    c = np.clip((np.trace(R) - 1) / 2, -1.0, 1.0)
    th = math.acos(c)
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    if th < 1e-9:
        return w / 2
    return th / (2 * math.sin(th)) * w
