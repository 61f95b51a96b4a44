"""The unknown-satellite pose tests' synthetic arc (test helper, not part of renderlab): a camera, six body points,
and a sequence of noisy detections of them along a Clohessy-Wiltshire arc with torque-free attitude."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from renderlab.dynamics.attitude import propagate_attitude
from renderlab.dynamics.relative_motion import cw_propagate, mean_motion
from renderlab.geometry.camera import CameraModel
from renderlab.geometry.rotations import look_at

CAM = CameraModel.from_dict({"width": 640, "height": 480, "fx": 554.0, "fy": 554.0, "cx": 319.5, "cy": 239.5})
PTS = np.array([[0.8, 0.2, 0.5], [-0.6, 0.7, -0.4], [0.1, -0.9, 0.6], [-0.5, -0.4, -0.7], [0.7, -0.5, -0.3],
                [-0.2, 0.6, 0.8]])


def synthetic_sequence(frames=60, dt=0.1, sigma=0.3, seed=0, w0_deg_s=(1.5, 3.6, 1.5)):
    n = mean_motion(600e3)
    times = np.arange(frames) * dt
    rv = cw_propagate([0.05, -4.6, 0.05, 0.01, -0.12, 0.005], n, times)
    I = np.array([1.6, 2.1, 2.6])
    q0 = np.array([0.2, -0.1, 0.3, 0.93])
    Q, W = propagate_attitude(q0 / np.linalg.norm(q0), np.radians(w0_deg_s), I, n, times)
    d = np.array([0.0, -0.6, 0.0])
    R_lc = look_at(d, d + [0, -1, 0], [1, 0, 0]).as_matrix()
    Rs = Rotation.from_quat(Q).as_matrix()
    rng = np.random.default_rng(seed)
    det = []
    for k in range(frames):
        z = CAM.project((rv[k, :3] + PTS @ Rs[k].T - d) @ R_lc)
        det.append(z + rng.normal(0, sigma, z.shape))
    return dict(n=n, times=times, rv=rv, R=Rs, W=W, I=I, d=d, R_lc=R_lc, det=det)
