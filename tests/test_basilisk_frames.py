"""Basilisk's conventions in the lab (renderlab.basilisk.frames), against Basilisk's own RigidBodyKinematics.

Oracle: the Basilisk chain written here from Basilisk's documented conventions, with its ``RigidBodyKinematics``
MRP → DCM (``MRP2C``): a planet-fixed point goes to inertial by ``J20002Pfix``ᵀ, to the body by ``C(σ_BN)``, to the
camera by ``C(σ_CB)`` about the camera position ``cameraPos_B``, and to a pixel by the square-pixel pinhole of
``CameraConfigMsgPayload`` (``fieldOfView`` edge to edge along y) with the principal point that
``pixelLineConverter`` removes (``u − W/2 + 0.5``). The lab projects the same point with its own camera model from the
pose ``frames.camera_pose`` builds. Positions are drawn at the scale of an orbit about the planet (a central-body
frame, as Basilisk's OpNav scenarios use); heliocentric coordinates (~2e11 m) carry ε·|r| ≈ 2e-5 m of float64
rounding in either chain. Skipped outside CI without Basilisk; in CI (``CI=true``) a missing Basilisk fails.
"""

from __future__ import annotations

import os

import numpy as np
import pytest


def _basilisk_or_skip():
    try:
        from Basilisk.utilities import RigidBodyKinematics
    except ImportError as exc:
        msg = f"Basilisk is not installed (the 'basilisk' extra: pip install -e '.[basilisk]'): {exc}"
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail(f"CI=true but {msg}", pytrace=False)
        pytest.skip(msg)
    return RigidBodyKinematics


@pytest.fixture(scope="module")
def rbk():
    return _basilisk_or_skip()


def _random_mrp(rng) -> np.ndarray:
    """MRPs of every size: short sets and shadow sets (|σ| up to 3)."""
    d = rng.normal(size=3)
    return d / np.linalg.norm(d) * rng.uniform(0.0, 3.0)


def test_mrp_quaternion_dcm_conversions_equal_basilisk(rbk):
    from renderlab.basilisk import frames

    rng = np.random.default_rng(20260)
    for _ in range(1000):
        s = _random_mrp(rng)
        C = rbk.MRP2C(s)
        assert np.max(np.abs(frames.mrp_to_dcm(s) - C)) <= 1e-13
        ep = np.asarray(rbk.MRP2EP(s), float)
        assert np.max(np.abs(frames.mrp_to_quat_wxyz(s) - ep)) <= 1e-13   # same set, same sign as Basilisk
        short = np.asarray(rbk.C2MRP(C), float)                               # Basilisk's short set of the DCM
        assert np.linalg.norm(short) <= 1.0 + 1e-12
        assert np.max(np.abs(frames.dcm_to_mrp(C) - short)) <= 1e-10
        assert np.max(np.abs(frames.quat_wxyz_to_mrp(ep) - short)) <= 1e-10
        if ep[0] >= 0:                                                        # then Basilisk's set is the short one
            assert np.max(np.abs(frames.quat_wxyz_to_mrp(ep) - np.asarray(rbk.EP2MRP(ep), float))) <= 1e-12
        assert np.max(np.abs(frames.mrp_to_dcm(frames.quat_wxyz_to_mrp(-ep)) - C)) <= 1e-12  # −β is the same DCM


def _oracle_pixels(rbk, p_P, sc, fov, W, H):
    """Basilisk's chain (module docstring) for points ``p_P`` (n, 3) in the planet-fixed frame."""
    BN, CB = rbk.MRP2C(sc["sigma_BN"]), rbk.MRP2C(sc["sigma_CB"])
    p_N = p_P @ sc["PN"] + sc["r_PN_N"]                    # J20002Pfix maps inertial → planet-fixed components
    cam_N = sc["r_BN_N"] + BN.T @ sc["cameraPos_B"]
    p_C = (p_N - cam_N) @ BN.T @ CB.T
    X = 2.0 * np.tan(fov / 2.0) / H                        # pixel pitch over focal length, square pixels
    u = p_C[:, 0] / p_C[:, 2] / X + W / 2.0 - 0.5
    v = p_C[:, 1] / p_C[:, 2] / X + H / 2.0 - 0.5
    return np.column_stack([u, v]), p_C


def test_lab_projection_from_the_basilisk_pose_equals_basilisk_chain_on_1000_poses(rbk):
    from renderlab.basilisk import frames

    rng = np.random.default_rng(7)
    worst = 0.0
    for _ in range(1000):
        W, H = (int(v) for v in rng.integers(16, 2049, size=2))
        fov = np.radians(rng.uniform(2.0, 120.0))
        sc = {"sigma_BN": _random_mrp(rng), "sigma_CB": _random_mrp(rng), "cameraPos_B": rng.normal(size=3) * 2.0,
              "r_BN_N": rng.normal(size=3) * 2e7, "r_PN_N": rng.normal(size=3) * 1e7,
              "PN": rbk.MRP2C(_random_mrp(rng))}
        pose = frames.camera_pose(sc["r_BN_N"], sc["sigma_BN"], sigma_CB=sc["sigma_CB"],
                                  cameraPos_B=sc["cameraPos_B"], r_PN_N=sc["r_PN_N"], dcm_PN=sc["PN"])
        cam = frames.camera_model(fov, (W, H))
        # points in the planet-fixed frame, in front of the camera (drawn in the lab pose, then each side projects)
        tan_half = np.tan(fov / 2.0)
        d = np.column_stack([rng.uniform(-1, 1, 20) * tan_half * W / H, rng.uniform(-1, 1, 20) * tan_half,
                             np.ones(20)]) * rng.uniform(1e6, 3e7, (20, 1))
        p_P = pose.rotation.apply(d) + pose.position_m
        want, p_C = _oracle_pixels(rbk, p_P, sc, fov, W, H)
        assert np.all(p_C[:, 2] > 0)
        got = cam.project(pose.rotation.inv().apply(p_P - pose.position_m))
        worst = max(worst, float(np.max(np.abs(got - want))))
    print(f"worst |lab − Basilisk chain| over 1000 poses × 20 points: {worst:.2e} px")
    assert worst <= 1e-6, worst


def test_sun_direction_and_camera_model():
    from renderlab.basilisk import frames
    from renderlab.errors import UserError

    PN = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # the planet-fixed x axis is inertial y
    s = frames.sun_direction([0.0, 3e11, 0.0], [0.0, 1e11, 0.0], PN)
    assert np.allclose(s, [1.0, 0.0, 0.0])
    cam = frames.camera_model(np.radians(90.0), (640, 480))
    assert (cam.fx, cam.fy, cam.cx, cam.cy) == pytest.approx((240.0, 240.0, 319.5, 239.5))
    with pytest.raises(UserError, match="fieldOfView"):
        frames.camera_model(4.0, (64, 64))
    with pytest.raises(UserError, match="J20002Pfix"):
        frames.camera_pose([1e7, 0, 0], [0, 0, 0], dcm_PN=np.ones((3, 3)))
