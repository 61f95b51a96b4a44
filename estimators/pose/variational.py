r"""Onboard attitude propagation (Ivanov et al. 2018, eq. 2) with its variational equations (numba RK4).

Euler's equations with gravity-gradient torque for principal moments I, written with the three
coefficients that are all the dynamics depend on (ratios only — the reason the inertia scale is
unobservable, eq. 7):

    ω̇₁ = a₁ (k γ₂γ₃ − ω₂ω₃),  ω̇₂ = a₂ (k γ₃γ₁ − ω₃ω₁),  ω̇₃ = a₃ (k γ₁γ₂ − ω₁ω₂),
    a₁ = (I₃−I₂)/I₁,  a₂ = (I₁−I₃)/I₂,  a₃ = (I₂−I₁)/I₃,  k = 3n²,  γ = Rᵀx̂ (first row of R),
    Ṙ = R [ω − n Rᵀẑ]×                      (R = R_lvlh_from_body, ω absolute, body frame).

For parameters θ_p ∈ {δφ₀ (3), ω₀ (3), ln I (2 or 3)} the sensitivities S_R = ∂R/∂θ_p and
S_ω = ∂ω/∂θ_p obey the variational equations, integrated with the same RK4 steps as the state:

    Ṡ_R = S_R [ω_rel]× + R [S_ω − n S_Rᵀẑ]×,
    Ṡ_ω,i = (∂a_i/∂θ_p)(k γ_jγ_k − ω_jω_k) + a_i (k(δγ_j γ_k + γ_j δγ_k) − (S_ω,j ω_k + ω_j S_ω,k)),
    δγ = first row of S_R;  S_R(0) = R₀ [J_r(δφ₀) e_p]× for δφ₀ (R₀ = R_ref exp([δφ₀]×)), S_ω(0) = e_p for ω₀.

This gives the exact derivative of the discrete RK4 map (the Jacobian of the model actually used in
the residuals of eq. 6), for ``scipy.optimize.least_squares(jac=...)`` and the Fisher matrix (eq. 7).
R is not re-orthonormalised (RK4 at |ω|h < 0.01 rad keeps ‖RᵀR − 1‖ at round-off over thousands of steps).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def _deriv(R, w, SR, Sw, a, da, k, n, dR, dw, dSR, dSw):
    P = SR.shape[0]
    g0, g1, g2 = R[0, 0], R[0, 1], R[0, 2]
    r0 = w[0] - n * R[2, 0]
    r1 = w[1] - n * R[2, 1]
    r2 = w[2] - n * R[2, 2]
    for i in range(3):  # dR = R [wr]x
        dR[i, 0] = R[i, 1] * r2 - R[i, 2] * r1
        dR[i, 1] = R[i, 2] * r0 - R[i, 0] * r2
        dR[i, 2] = R[i, 0] * r1 - R[i, 1] * r0
    c0 = k * g1 * g2 - w[1] * w[2]
    c1 = k * g2 * g0 - w[2] * w[0]
    c2 = k * g0 * g1 - w[0] * w[1]
    dw[0] = a[0] * c0
    dw[1] = a[1] * c1
    dw[2] = a[2] * c2
    for p in range(P):
        e0 = Sw[p, 0] - n * SR[p, 2, 0]
        e1 = Sw[p, 1] - n * SR[p, 2, 1]
        e2 = Sw[p, 2] - n * SR[p, 2, 2]
        for i in range(3):
            dSR[p, i, 0] = SR[p, i, 1] * r2 - SR[p, i, 2] * r1 + R[i, 1] * e2 - R[i, 2] * e1
            dSR[p, i, 1] = SR[p, i, 2] * r0 - SR[p, i, 0] * r2 + R[i, 2] * e0 - R[i, 0] * e2
            dSR[p, i, 2] = SR[p, i, 0] * r1 - SR[p, i, 1] * r0 + R[i, 0] * e1 - R[i, 1] * e0
        h0, h1, h2 = SR[p, 0, 0], SR[p, 0, 1], SR[p, 0, 2]
        s0, s1, s2 = Sw[p, 0], Sw[p, 1], Sw[p, 2]
        dSw[p, 0] = da[0, p] * c0 + a[0] * (k * (h1 * g2 + g1 * h2) - (s1 * w[2] + w[1] * s2))
        dSw[p, 1] = da[1, p] * c1 + a[1] * (k * (h2 * g0 + g2 * h0) - (s2 * w[0] + w[2] * s0))
        dSw[p, 2] = da[2, p] * c2 + a[2] * (k * (h0 * g1 + g0 * h1) - (s0 * w[1] + w[0] * s1))


@njit(cache=True)
def _propagate(R0, w0, SR0, Sw0, a, da, n, times, substeps, outR, outW, outSR, outSw):
    k = 3.0 * n * n
    P = SR0.shape[0]
    R = R0.copy()
    w = w0.copy()
    SR = SR0.copy()
    Sw = Sw0.copy()
    kR = np.empty((4, 3, 3))
    kw = np.empty((4, 3))
    kSR = np.empty((4, P, 3, 3))
    kSw = np.empty((4, P, 3))
    Rt = np.empty((3, 3))
    wt = np.empty(3)
    SRt = np.empty((P, 3, 3))
    Swt = np.empty((P, 3))
    outR[0] = R
    outW[0] = w
    outSR[0] = SR
    outSw[0] = Sw
    for m in range(times.shape[0] - 1):
        h = (times[m + 1] - times[m]) / substeps
        for _ in range(substeps):
            for st in range(4):
                if st == 0:
                    Rt[:] = R
                    wt[:] = w
                    SRt[:] = SR
                    Swt[:] = Sw
                else:
                    c = h if st == 3 else 0.5 * h
                    Rt[:] = R + c * kR[st - 1]
                    wt[:] = w + c * kw[st - 1]
                    SRt[:] = SR + c * kSR[st - 1]
                    Swt[:] = Sw + c * kSw[st - 1]
                _deriv(Rt, wt, SRt, Swt, a, da, k, n, kR[st], kw[st], kSR[st], kSw[st])
            R += h / 6.0 * (kR[0] + 2.0 * kR[1] + 2.0 * kR[2] + kR[3])
            w += h / 6.0 * (kw[0] + 2.0 * kw[1] + 2.0 * kw[2] + kw[3])
            SR += h / 6.0 * (kSR[0] + 2.0 * kSR[1] + 2.0 * kSR[2] + kSR[3])
            Sw += h / 6.0 * (kSw[0] + 2.0 * kSw[1] + 2.0 * kSw[2] + kSw[3])
        outR[m + 1] = R
        outW[m + 1] = w
        outSR[m + 1] = SR
        outSw[m + 1] = Sw


def _skew(v):
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def right_jacobian_so3(phi) -> np.ndarray:
    """J_r(φ): exp([φ + δ]×) ≈ exp([φ]×) exp([J_r δ]×) for small δ."""
    phi = np.asarray(phi, float)
    th = float(np.linalg.norm(phi))
    K = _skew(phi)
    if th < 1e-8:
        return np.eye(3) - 0.5 * K + K @ K / 6.0
    return np.eye(3) - (1 - math.cos(th)) / th**2 * K + (th - math.sin(th)) / th**3 * K @ K


def inertia_coefficients(log_inertia) -> tuple[np.ndarray, np.ndarray]:
    """(a (3,), ∂a/∂ln I (3, 3)) of the module docstring for ln I = (ln I1, ln I2, ln I3)."""
    I1, I2, I3 = np.exp(np.asarray(log_inertia, float))
    a = np.array([(I3 - I2) / I1, (I1 - I3) / I2, (I2 - I1) / I3])
    da = np.array([[-a[0], -I2 / I1, I3 / I1],
                   [I1 / I2, -a[1], -I3 / I2],
                   [-I1 / I3, I2 / I3, -a[2]]])
    return a, da


def propagate(R0, w0, log_inertia, n: float, times, substeps: int = 2, SR0=None, Sw0=None, da_params=None):
    """RK4 of eq. 2 (and, if given, of the variational equations for P parameters).

    Parameters
    ----------
    R0, w0 : initial ``R_lvlh_from_body`` (3, 3) and absolute body rate (3,) at ``times[0]``.
    log_inertia : (ln I1, ln I2, ln I3).
    SR0, Sw0 : (P, 3, 3), (P, 3) initial sensitivities; ``da_params`` (3, P): ∂a/∂θ_p (0 for non-inertia θ_p).

    Returns
    -------
    R (N, 3, 3), W (N, 3), SR (N, P, 3, 3), SW (N, P, 3)
    """
    times = np.ascontiguousarray(times, float)
    a, _ = inertia_coefficients(log_inertia)
    P = 0 if SR0 is None else len(SR0)
    SR0 = np.zeros((P, 3, 3)) if SR0 is None else np.ascontiguousarray(SR0, float)
    Sw0 = np.zeros((P, 3)) if Sw0 is None else np.ascontiguousarray(Sw0, float)
    da = np.zeros((3, P)) if da_params is None else np.ascontiguousarray(da_params, float)
    N = len(times)
    outR, outW = np.empty((N, 3, 3)), np.empty((N, 3))
    outSR, outSw = np.empty((N, P, 3, 3)), np.empty((N, P, 3))
    R0 = np.ascontiguousarray(R0, float)
    w0 = np.ascontiguousarray(w0, float)
    if not (np.all(np.isfinite(R0)) and np.all(np.isfinite(w0)) and np.all(np.isfinite(a))):
        raise ValueError("non-finite attitude state or inertia")
    _propagate(R0, w0, SR0, Sw0, a, da, float(n), times, int(substeps), outR, outW, outSR, outSw)
    if not np.all(np.isfinite(outR)):
        raise ValueError("attitude integration diverged")
    return outR, outW, outSR, outSw


def propagate_with_sensitivities(R_ref, dphi0, w0, log_inertia, n: float, times, substeps: int = 2,
                                 inertia_params: int = 2):
    """State and sensitivities to θ_att = (δφ₀ (3), ω₀ (3), ln I1, ln I2[, ln I3]) (P = 6 + inertia_params).

    ``inertia_params`` = 2: ln I3 is held (ratio form, I3 ≡ 1); = 3: all three log-moments.
    """
    P = 6 + inertia_params
    E = _expm(dphi0)
    R0 = np.asarray(R_ref, float) @ E
    Jr = right_jacobian_so3(dphi0)
    SR0 = np.zeros((P, 3, 3))
    Sw0 = np.zeros((P, 3))
    for p in range(3):
        SR0[p] = R0 @ _skew(Jr[:, p])
        Sw0[3 + p, p] = 1.0
    _, dA = inertia_coefficients(log_inertia)
    da = np.zeros((3, P))
    da[:, 6:] = dA[:, :inertia_params]
    return propagate(R0, w0, log_inertia, n, times, substeps, SR0, Sw0, da)


def _expm(v) -> np.ndarray:
    v = np.asarray(v, float)
    th = float(np.linalg.norm(v))
    K = _skew(v)
    if th < 1e-12:
        return np.eye(3) + K
    return np.eye(3) + math.sin(th) / th * K + (1 - math.cos(th)) / th**2 * K @ K
