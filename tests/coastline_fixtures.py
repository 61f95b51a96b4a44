"""The coastline-EKF tests' orbits and filter problems (test helper, not part of renderlab): a circular orbit at
1000 km and a random batch filter problem (states, covariances, coastline points, attitudes) for the eq. 19 gain."""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial.transform import Rotation

from estimators.coastline.dynamics import MU_EARTH
from estimators.coastline.ekf import BatchCoastlineEKF, EKFOptions
from estimators.coastline.los import los_predict

A_1000 = 6378137.0 + 1.0e6


def circular_state(a=A_1000, inc=math.radians(45.0)):
    v = math.sqrt(MU_EARTH / a)
    return np.array([a, 0.0, 0.0, 0.0, v * math.cos(inc), v * math.sin(inc)])


def random_filter_problem(seed, N=4, m=5, sigma_att=3e-5, method="woodbury"):
    rng = np.random.default_rng(seed)
    x = np.tile(circular_state(), (N, 1)) + np.c_[rng.normal(0, 500, (N, 3)), rng.normal(0, 0.005, (N, 3))]
    L = rng.normal(size=(N, 6, 6)) * np.r_[np.full(3, 300.0), np.full(3, 0.3)][None, :, None]
    P0 = L @ np.swapaxes(L, 1, 2) + np.diag(np.r_[np.full(3, 100.0), np.full(3, 1e-4)])
    o = x[0, :3] * (6378137.0 / A_1000) + rng.normal(0, 1.5e5, (m, 3))
    T = np.tile(Rotation.from_rotvec(rng.normal(0, 1, 3)).as_matrix(), (N, 1, 1))
    y = los_predict(x[:, :3] + rng.normal(0, 300, (N, 3)), o, T)[0]
    f = BatchCoastlineEKF(x, P0, EKFOptions(sigma_theta_rad=4e-4, sigma_attitude_rad=sigma_att, gain_method=method))
    return f, y, o, T
