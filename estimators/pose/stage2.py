r"""Stage 2 (Ivanov et al. 2018, §6): per-frame least-squares pose and a constant-gain Kalman filter.

Description
-----------
Per frame: the points of the stage-1 catalogue are projected with the filter's predicted pose; the
detected centre nearest to each projection within ε is its measurement. With ≥ 4 non-coplanar points
the pose (r, R_lvlh_from_body) minimising eq. 8, Σ_j ‖z_j − ẑ_j‖², is found by Gauss-Newton
(``scipy.optimize.least_squares``) from the prediction — eq. 9 gives ẑ as a function of the centre of
mass and the attitude. Fewer points or (nearly) coplanar points leave the frame without a measurement
(flagged ``TOO_FEW_POINTS`` / ``COPLANAR``, prediction only; a failed solve is ``PNP_FAILED``);
:func:`solve_pose` itself raises :class:`EstimationError` for them.

Filter (eq. 10): x̂_k = x̃_k + K (z_k − H x̃_k) with constant K. The prediction x̃ integrates the onboard
model (CW, Euler + gravity gradient with the stage-1 inertia ratios). K is the steady-state Kalman
gain of a per-axis constant-velocity model (position/angle measured, white acceleration σ_a), from the
discrete algebraic Riccati equation (:func:`steady_gains`, computed once from the first measurement's
covariance and the median frame interval); the attitude innovation is the rotation vector
log(R_meas R̃ᵀ) in LVLH, applied as R ← exp(α δ) R̃, ω ← ω + (β/dt) R̃ᵀ δ.

Tuning
------
:class:`Stage2Options`:

==========================  =======  =========================================================================
knob                        default  turn it when
==========================  =======  =========================================================================
``epsilon_px``              10.0     ε-neighbourhood of the association: the detected centre nearest each
                                     projected catalogue point within ε is its measurement; raise for fast
                                     motion or poor prediction, lower in clutter
``sigma_px``                0.3      centroid noise, px: the measurement covariance σ²(JᵀJ)⁻¹ of the first PnP
                                     fix, hence the gains
``sigma_accel_mps2``        2e-3     unmodelled translational acceleration of the constant-velocity model:
                                     larger → larger α, β (follows the measurements)
``sigma_ang_accel_rad_s2``  5e-3     unmodelled angular acceleration, the same for the attitude gains
``min_planarity``           0.05     smallest/largest singular value of the centred points under which they
                                     count as coplanar (``COPLANAR``, no measurement)
``substeps``                2        RK4 steps per frame interval of the prediction
==========================  =======  =========================================================================

Use
---
::

    from estimators.pose import Stage2Options, run_stage2
    out = run_stage2(detections, frames, times_s, camera, R_lvlh_from_cam, d_lvlh, n_rad_s, s1.points_body,
                     s1.inertia_ratios, s1.r0_lvlh, s1.v0_lvlh, s1.R0_lvlh_from_body, s1.omega0_body,
                     Stage2Options(epsilon_px=10.0))                     # s1: the stage-1 result
    out.r, out.R, out.w, out.flags, out.gains                           # per frame: LVLH position, attitude, rate

References
----------
D. Ivanov et al., "Relative Pose and Inertia Determination of Unknown Satellite Using Monocular Vision",
International Journal of Aerospace Engineering, vol. 2018, Article ID 9731512, 9 pages, 2018.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .onboard_model import cw_transition, exp_so3, log_so3, predict_pixels, propagate_rotation
from .stage1 import EstimationError

TOO_FEW_POINTS = 1
COPLANAR = 2
PNP_FAILED = 4
FLAG_NAMES = {TOO_FEW_POINTS: "too_few_points", COPLANAR: "coplanar_points", PNP_FAILED: "pnp_failed"}


def coplanarity(points: np.ndarray) -> float:
    """Smallest / largest singular value of the centred points (0 = coplanar or collinear)."""
    p = np.asarray(points, float)
    s = np.linalg.svd(p - p.mean(0), compute_uv=False)
    return float(s[-1] / s[0]) if s[0] > 0 else 0.0


def solve_pose(points_body, sl, camera, R_cam_from_body0, t_cam0, min_planarity: float = 0.05):
    """Least-squares pose (eq. 8) in the camera frame: ``p_cam = R p_body + t``.

    Returns (R_cam_from_body, t_cam, rms_px, J) where J is the whitened-free Jacobian (2M × 6) at the
    solution (for covariance σ²(JᵀJ)⁻¹). Raises EstimationError for < 4 points or coplanar points.
    """
    from scipy.optimize import least_squares

    P = np.asarray(points_body, float)
    z = np.asarray(sl, float)
    if len(P) < 4:
        raise EstimationError(f"pose needs at least 4 points, got {len(P)}")
    if coplanarity(P) < min_planarity:
        raise EstimationError(f"pose points are (nearly) coplanar (thickness ratio {coplanarity(P):.3f} "
                              f"< {min_planarity})")
    R0 = np.asarray(R_cam_from_body0, float)

    def fun(x):
        R = exp_so3(x[:3]) @ R0
        pred = camera.project(P @ R.T + x[3:])
        r = (pred - z).ravel()
        return np.where(np.isfinite(r), r, 1e4)

    sol = least_squares(fun, np.r_[np.zeros(3), t_cam0], method="lm", xtol=1e-12, ftol=1e-12)
    R = exp_so3(sol.x[:3]) @ R0
    return R, sol.x[3:], float(np.sqrt(np.mean(sol.fun**2))), sol.jac


def steady_gains(dt: float, sigma_meas: float, sigma_accel: float) -> tuple[float, float]:
    """(α, β) of the steady-state Kalman filter for x = [pos, vel], z = pos (per axis)."""
    from scipy.linalg import solve_discrete_are

    F = np.array([[1.0, dt], [0.0, 1.0]])
    H = np.array([[1.0, 0.0]])
    G = np.array([[dt * dt / 2], [dt]])
    Q = G @ G.T * sigma_accel**2 + 1e-30 * np.eye(2)
    R = np.array([[sigma_meas**2]])
    P = solve_discrete_are(F.T, H.T, Q, R)  # a-priori steady covariance
    K = P @ H.T / (H @ P @ H.T + R)
    return float(K[0, 0]), float(K[1, 0] * dt)


@dataclass(frozen=True)
class Stage2Options:
    epsilon_px: float = 10.0
    sigma_px: float = 0.3
    sigma_accel_mps2: float = 2e-3        # unmodelled translational acceleration
    sigma_ang_accel_rad_s2: float = 5e-3  # unmodelled angular acceleration
    min_planarity: float = 0.05
    substeps: int = 2


@dataclass
class Stage2Result:
    frames: np.ndarray
    r: np.ndarray           # (N, 3) LVLH
    v: np.ndarray
    R: np.ndarray           # (N, 3, 3) R_lvlh_from_body
    w: np.ndarray           # (N, 3) body, absolute
    r_meas: np.ndarray      # (N, 3) per-frame LSQ position (NaN when none)
    R_meas: np.ndarray
    n_points: np.ndarray
    rms_px: np.ndarray
    flags: np.ndarray
    gains: dict = field(default_factory=dict)


def run_stage2(detections: list[np.ndarray], frames, times_s, camera, R_lvlh_from_cam, d_lvlh, n: float,
               points_body, inertia_ratios, r0, v0, R0, w0, opts: Stage2Options = Stage2Options()) -> Stage2Result:
    """Run the per-frame LSQ + constant-gain filter over ``frames`` from the initial state at ``frames[0]``."""
    P = np.asarray(points_body, float)
    inertia = np.r_[inertia_ratios, 1.0]
    r, v, R, w = np.array(r0, float), np.array(v0, float), np.array(R0, float), np.array(w0, float)
    out = {k: [] for k in ("r", "v", "R", "w", "r_meas", "R_meas", "n_points", "rms_px", "flags")}
    gains = None
    for i, f in enumerate(frames):
        if i > 0:
            dt = times_s[f] - times_s[frames[i - 1]]
            rv = cw_transition(n, dt) @ np.r_[r, v]
            r, v = rv[:3], rv[3:]
            Rs, Ws = propagate_rotation(R, w, inertia, n, [0.0, dt], opts.substeps)
            R, w = Rs[-1], Ws[-1]
        pred = predict_pixels(camera, R_lvlh_from_cam, d_lvlh, r, R, P)
        det = np.asarray(detections[i], float).reshape(-1, 2)
        use_p, use_z = [], []
        if len(det):
            for j, q in enumerate(pred):
                if not np.all(np.isfinite(q)):
                    continue
                dist = np.hypot(*(det - q).T)
                m = int(np.argmin(dist))
                if dist[m] <= opts.epsilon_px:
                    use_p.append(P[j])
                    use_z.append(det[m])
        flag, r_m, R_m, rms = 0, np.full(3, np.nan), np.full((3, 3), np.nan), np.nan
        if len(use_p) < 4:
            flag = TOO_FEW_POINTS
        elif coplanarity(np.array(use_p)) < opts.min_planarity:
            flag = COPLANAR
        else:
            R_cb0 = R_lvlh_from_cam.T @ R
            t0 = R_lvlh_from_cam.T @ (r - d_lvlh)
            try:
                R_cb, t_c, rms, J = solve_pose(np.array(use_p), np.array(use_z), camera, R_cb0, t0, opts.min_planarity)
                R_m = R_lvlh_from_cam @ R_cb
                r_m = R_lvlh_from_cam @ t_c + d_lvlh
            except (EstimationError, np.linalg.LinAlgError, ValueError):
                flag = PNP_FAILED
        if flag == 0:
            if gains is None:  # measurement noise from the first LSQ covariance σ²(JᵀJ)⁻¹
                cov = opts.sigma_px**2 * np.linalg.inv(J.T @ J)
                s_ang, s_pos = np.sqrt(np.mean(np.diag(cov)[:3])), np.sqrt(np.mean(np.diag(cov)[3:]))
                dt_nom = float(np.median(np.diff(times_s)))
                ar, br = steady_gains(dt_nom, s_pos, opts.sigma_accel_mps2)
                aq, bq = steady_gains(dt_nom, s_ang, opts.sigma_ang_accel_rad_s2)
                gains = {"alpha_r": ar, "beta_r": br, "alpha_q": aq, "beta_q": bq, "dt": dt_nom,
                         "sigma_pos_m": s_pos, "sigma_ang_rad": s_ang}
            dr = r_m - r
            r = r + gains["alpha_r"] * dr
            v = v + gains["beta_r"] / gains["dt"] * dr
            dq = log_so3(R_m @ R.T)            # LVLH-frame rotation error
            w = w + gains["beta_q"] / gains["dt"] * (R.T @ dq)
            R = exp_so3(gains["alpha_q"] * dq) @ R
        for k, val in zip(("r", "v", "R", "w", "r_meas", "R_meas", "n_points", "rms_px", "flags"),
                          (r, v, R, w, r_m, R_m, len(use_p), rms, flag)):
            out[k].append(np.copy(val))
    return Stage2Result(np.asarray(frames), *(np.array(out[k]) for k in
                                              ("r", "v", "R", "w", "r_meas", "R_meas", "n_points", "rms_px", "flags")),
                        gains=gains or {})
