"""Stage 2 (per-frame least-squares pose + constant-gain Kalman filter) against independent oracles.

* solve_pose vs OpenCV's SQPnP (cv2.solvePnP(..., SOLVEPNP_SQPNP)): exact data → both exact; noisy
  data → our least squares has reprojection RMS ≤ SQPnP's (it minimises it), and the two poses agree
  within 4σ of the CRLB σ²(JᵀJ)⁻¹.
* < 4 points and coplanar points raise EstimationError; run_stage2 flags such frames and keeps predicting.
* steady_gains equals the limit of the Riccati recursion iterated by hand.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from pose_fixtures import CAM, PTS, synthetic_sequence
from scipy.spatial.transform import Rotation

from estimators.pose import EstimationError, Stage2Options, run_stage2, solve_pose, steady_gains
from estimators.pose.stage2 import COPLANAR, TOO_FEW_POINTS


def _sqpnp(P, z):
    K = CAM.K_matrix
    ok, rvec, tvec = cv2.solvePnP(P.astype(np.float64), z.astype(np.float64), K, None, flags=cv2.SOLVEPNP_SQPNP)
    assert ok
    return cv2.Rodrigues(rvec)[0], tvec.ravel()


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_solve_pose_agrees_with_sqpnp(seed):
    rng = np.random.default_rng(seed)
    R = Rotation.random(random_state=seed).as_matrix()
    t = np.array([0.2, -0.1, 4.0]) + rng.normal(0, 0.2, 3)
    z0 = CAM.project(PTS @ R.T + t)
    # exact data: both exact
    Rs, ts = _sqpnp(PTS, z0)
    Rl, tl, rms, _ = solve_pose(PTS, z0, CAM, Rotation.from_rotvec(rng.normal(0, 0.1, 3)).as_matrix() @ R, t + 0.1)
    assert np.allclose(Rs, R, atol=1e-6) and np.allclose(ts, t, atol=1e-6)
    assert np.allclose(Rl, R, atol=1e-9) and np.allclose(tl, t, atol=1e-9) and rms < 1e-8
    # noisy data
    sigma = 0.3
    z = z0 + rng.normal(0, sigma, z0.shape)
    Rs, ts = _sqpnp(PTS, z)
    Rl, tl, rms, J = solve_pose(PTS, z, CAM, Rs, ts)
    rms_sq = np.sqrt(np.mean((CAM.project(PTS @ Rs.T + ts) - z) ** 2))
    assert rms <= rms_sq + 1e-9
    sig = np.sqrt(np.diag(sigma**2 * np.linalg.inv(J.T @ J)))
    dphi = Rotation.from_matrix(Rs @ Rl.T).as_rotvec()
    assert np.all(np.abs(dphi) < 4 * sig[:3] + 1e-9), (dphi, sig[:3])
    assert np.all(np.abs(ts - tl) < 4 * np.maximum(sig[3:], 1e-12) + 4 * np.abs(np.cross(dphi, tl))), (ts - tl, sig[3:])
    # the LSQ estimate is near the truth in CRLB units (estimator sanity)
    assert np.all(np.abs(tl - t) < 5 * sig[3:])


def test_solve_pose_refuses_bad_point_sets():
    R, t = np.eye(3), np.array([0, 0, 4.0])
    with pytest.raises(EstimationError, match="at least 4"):
        solve_pose(PTS[:3], CAM.project(PTS[:3] + t), CAM, R, t)
    flat = PTS.copy()
    flat[:, 2] = 0.0
    with pytest.raises(EstimationError, match="coplanar"):
        solve_pose(flat, CAM.project(flat + t), CAM, R, t)


def test_steady_gains_match_riccati_iteration():
    dt, sm, sa = 0.1, 0.01, 0.02
    a, b = steady_gains(dt, sm, sa)
    F = np.array([[1, dt], [0, 1]])
    G = np.array([[dt * dt / 2], [dt]])
    Q, P, H = G @ G.T * sa**2, np.eye(2), np.array([[1.0, 0.0]])
    for _ in range(5000):
        K = P @ H.T / (H @ P @ H.T + sm**2)
        P = F @ ((np.eye(2) - K @ H) @ P) @ F.T + Q
    K = P @ H.T / (H @ P @ H.T + sm**2)
    assert np.isclose(a, K[0, 0], rtol=1e-6) and np.isclose(b, K[1, 0] * dt, rtol=1e-6)


def test_stage2_filter_tracks_and_flags_missing_points():
    s = synthetic_sequence()
    det = list(s["det"])
    det[20] = det[20][:3]          # only 3 points in frame 20
    frames = np.arange(len(det))
    out = run_stage2(det, frames, s["times"], CAM, s["R_lc"], s["d"], s["n"], PTS, s["I"][:2] / s["I"][2],
                     s["rv"][0, :3] + 0.02, s["rv"][0, 3:] + 0.01, s["R"][0], s["W"][0],
                     Stage2Options(sigma_px=0.3))
    assert out.flags[20] == TOO_FEW_POINTS and np.all(np.isnan(out.r_meas[20]))
    assert np.sum(out.flags != 0) == 1
    e_meas = np.linalg.norm(out.r_meas - s["rv"][:, :3], axis=1)
    e_filt = np.linalg.norm(out.r - s["rv"][:, :3], axis=1)
    ok = out.flags == 0
    late = np.arange(len(det)) >= 20
    # the filter averages: smaller position error than the raw per-frame LSQ once converged
    assert np.sqrt(np.mean(e_filt[ok & late] ** 2)) < 0.8 * np.sqrt(np.mean(e_meas[ok & late] ** 2))
    e_v = np.linalg.norm(out.v - s["rv"][:, 3:], axis=1)
    assert np.sqrt(np.mean(e_v[late] ** 2)) < 0.5 * 0.01 * np.sqrt(2)  # below the initial 1 cm/s/axis error
    # a coplanar catalogue seen in every frame (all 6 points matched): flagged coplanar, no pose
    flat = PTS.copy()
    flat[:, 2] = 0.0
    det_flat = [CAM.project((s["rv"][k, :3] + flat @ s["R"][k].T - s["d"]) @ s["R_lc"]) for k in range(3)]
    out2 = run_stage2(det_flat, frames[:3], s["times"], CAM, s["R_lc"], s["d"], s["n"], flat,
                      s["I"][:2] / s["I"][2], s["rv"][0, :3], s["rv"][0, 3:], s["R"][0], s["W"][0])
    assert np.all(out2.flags == COPLANAR) and np.all(out2.n_points == 6) and np.all(np.isnan(out2.r_meas))
    # detections that belong to another object: nothing within ε, flagged too few (lost tracks), no pose
    out3 = run_stage2(det[:3], frames[:3], s["times"], CAM, s["R_lc"], s["d"], s["n"], flat,
                      s["I"][:2] / s["I"][2], s["rv"][0, :3], s["rv"][0, 3:], s["R"][0], s["W"][0])
    assert np.all(out3.flags == TOO_FEW_POINTS) and np.all(np.isnan(out3.r_meas))
