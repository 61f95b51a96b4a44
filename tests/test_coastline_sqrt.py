"""The square-root coastline EKF (array-form QR, tangent-basis LOS) against the eq. 19 / Joseph filter: the
same propagation, gain, covariance and NIS, the Joseph filter itself being pinned to a numpy pinv update in
``test_coastline_ekf.py``. Plus: P = SSᵀ stays symmetric positive definite by construction."""

from __future__ import annotations

import numpy as np
import pytest
from coastline_fixtures import random_filter_problem

from estimators.coastline.ekf import BatchCoastlineEKF, EKFOptions
from estimators.coastline.sqrt_ekf import SqrtBatchCoastlineEKF, tangent_basis


@pytest.mark.parametrize("sigma_att, q", [(0.0, 0.0), (3e-5, 0.0), (3e-5, 1e-9)])
def test_sqrt_filter_equals_joseph_filter(sigma_att, q):
    fj, y, o, T = random_filter_problem(11, sigma_att=sigma_att)
    opts = EKFOptions(sigma_theta_rad=4e-4, sigma_attitude_rad=sigma_att, q_acc_m2_s3=q)
    fj = BatchCoastlineEKF(fj.x, fj.P, opts)
    fs = SqrtBatchCoastlineEKF(fj.x, fj.P, opts)
    assert np.allclose(fs.P, fj.P, rtol=1e-12, atol=0)
    fj.propagate(30.0)
    fs.propagate(30.0)
    scale = np.abs(fj.P).max()
    assert np.allclose(fs.x, fj.x, rtol=0, atol=1e-9)
    assert np.allclose(fs.P, fj.P, rtol=1e-9, atol=1e-12 * scale)
    rj, rs = fj.update(y, o, T), fs.update(y, o, T)
    assert np.allclose(fs.x, fj.x, rtol=0, atol=1e-6)
    assert np.allclose(fs.P, fj.P, rtol=1e-7, atol=1e-12 * scale)
    assert np.allclose(rs.nis, rj.nis, rtol=1e-7)
    assert rs.dof == rj.dof == 2 * len(o)
    err = np.random.default_rng(0).normal(size=(fj.n_runs, 6)) * np.r_[np.full(3, 100.0), np.full(3, 0.1)]
    ref = np.einsum("ni,ni->n", err, np.linalg.solve(fj.P, err[..., None])[..., 0])
    assert np.allclose(fs.nees(err), ref, rtol=1e-7)


def test_tangent_basis_is_orthonormal_and_perpendicular():
    e = np.random.default_rng(2).normal(size=(50, 3))
    e /= np.linalg.norm(e, axis=1, keepdims=True)
    e[0] = [1.0, 0.0, 0.0]                                  # the helper-axis switch
    B = tangent_basis(e)
    assert np.allclose(np.einsum("nij,nkj->nik", B, B), np.eye(2), atol=1e-14)
    assert np.allclose(np.einsum("nij,nj->ni", B, e), 0.0, atol=1e-14)
