r"""Rigid-body attitude of the target: Euler's equations with gravity-gradient torque (Ivanov et al. eq. 2).

State: ``q`` — scalar-last unit quaternion of ``R_lvlh_from_body`` (the transpose of the paper's A, which
maps the orbital frame O to the body frame), and ``ω`` — the *absolute* angular velocity in the body frame.
With the principal inertia tensor ``I`` (body axes) and a circular orbit of mean motion n:

    I ω̇ + ω × Iω = 3n² γ × Iγ,        γ = Rᵀ x̂_O (radius-vector direction in the body frame),   (eq. 2)
    ω_rel = ω − n Rᵀ ẑ_O,              q̇ = ½ q ⊗ (ω_rel, 0)       (kinematics relative to LVLH).

Both are invariant under I → cI (absolute inertia is not observable from motion). Integration: classical
fixed-step RK4 with ``substeps`` steps between output times, quaternion renormalised each step.
Conserved when checked in tests: |Iω| and ½ωᵀIω when n = 0; the Jacobi integral
h = ½ω_relᵀIω_rel − ½n²βᵀIβ + (3/2)n²γᵀIγ (β = orbit normal in body) with gravity gradient.
"""

from __future__ import annotations

import numpy as np


def quat_mul(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product p ⊗ q of scalar-last quaternions (R(p⊗q) = R(p) R(q))."""
    pv, pw = p[:3], p[3]
    qv, qw = q[:3], q[3]
    return np.concatenate([pw * qv + qw * pv + np.cross(pv, qv), [pw * qw - pv @ qv]])


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of a scalar-last unit quaternion."""
    x, y, z, w = q / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def attitude_rhs(q: np.ndarray, w: np.ndarray, inertia: np.ndarray, n: float) -> tuple[np.ndarray, np.ndarray]:
    """(q̇, ω̇) of eq. 2 for principal moments ``inertia`` (3,)."""
    R = quat_to_matrix(q)
    gamma = R[0, :]  # Rᵀ x̂
    beta = R[2, :]   # Rᵀ ẑ
    Iw = inertia * w
    torque = 3.0 * n * n * np.cross(gamma, inertia * gamma)
    wdot = (torque - np.cross(w, Iw)) / inertia
    w_rel = w - n * beta
    qdot = 0.5 * quat_mul(q, np.array([w_rel[0], w_rel[1], w_rel[2], 0.0]))
    return qdot, wdot


def propagate_attitude(q0, w0, inertia, n: float, times, substeps: int = 20) -> tuple[np.ndarray, np.ndarray]:
    """Quaternions (N, 4) and body rates (N, 3) at ``times`` (s, increasing, times[0] is the epoch of q0, ω0)."""
    times = np.asarray(times, float).ravel()
    inertia = np.asarray(inertia, float)
    q = np.asarray(q0, float) / np.linalg.norm(q0)
    w = np.asarray(w0, float).copy()
    Q, W = [q.copy()], [w.copy()]
    for t0, t1 in zip(times[:-1], times[1:]):
        h = (t1 - t0) / substeps
        for _ in range(substeps):
            k1q, k1w = attitude_rhs(q, w, inertia, n)
            k2q, k2w = attitude_rhs(q + 0.5 * h * k1q, w + 0.5 * h * k1w, inertia, n)
            k3q, k3w = attitude_rhs(q + 0.5 * h * k2q, w + 0.5 * h * k2w, inertia, n)
            k4q, k4w = attitude_rhs(q + h * k3q, w + h * k3w, inertia, n)
            q = q + h / 6 * (k1q + 2 * k2q + 2 * k3q + k4q)
            w = w + h / 6 * (k1w + 2 * k2w + 2 * k3w + k4w)
            q /= np.linalg.norm(q)
        Q.append(q.copy())
        W.append(w.copy())
    return np.array(Q), np.array(W)


def jacobi_integral(q, w, inertia, n: float) -> float:
    """The conserved Jacobi integral of eq. 2 on a circular orbit (see module docstring)."""
    R = quat_to_matrix(np.asarray(q, float))
    I = np.asarray(inertia, float)
    gamma, beta = R[0, :], R[2, :]
    w_rel = np.asarray(w, float) - n * beta
    return float(0.5 * w_rel @ (I * w_rel) - 0.5 * n * n * beta @ (I * beta) + 1.5 * n * n * gamma @ (I * gamma))
