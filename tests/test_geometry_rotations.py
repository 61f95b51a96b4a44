"""Rotations and frames: look_at in the lab camera frame, quaternions (xyzw), transforms."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from renderlab.errors import UserError
from renderlab.geometry import (
    CameraModel,
    angle_between,
    as_axis_angle,
    axis_angle,
    invert_transform,
    look_at,
    quat_xyzw,
    rotation_from_matrix,
    rotation_from_quat_xyzw,
    skew,
    to_camera_frame,
    transform_points,
)

CAM = CameraModel(640, 480, 700.0, 700.0, 319.5, 239.5)


def _random_setups(n=50, seed=0):
    rng = np.random.default_rng(seed)
    for _ in range(n):
        pos = rng.normal(size=3) * 100
        tgt = rng.normal(size=3) * 10
        up = rng.normal(size=3)
        yield pos, tgt, up


def test_look_at_puts_target_on_boresight():
    for pos, tgt, up in _random_setups():
        R = look_at(pos, tgt, up)
        M = R.as_matrix()
        np.testing.assert_allclose(M.T @ M, np.eye(3), atol=1e-12)
        assert np.linalg.det(M) == pytest.approx(1.0, abs=1e-12)
        p_cam = to_camera_frame(R, pos, tgt)
        np.testing.assert_allclose(p_cam[:2], 0.0, atol=1e-9)
        assert p_cam[2] == pytest.approx(np.linalg.norm(tgt - pos))
        np.testing.assert_allclose(CAM.project(p_cam), [CAM.cx, CAM.cy], atol=1e-9)


def test_look_at_up_is_top_of_image_and_right_is_forward_cross_up():
    for pos, tgt, up in _random_setups(seed=1):
        R = look_at(pos, tgt, up)
        fwd = (tgt - pos) / np.linalg.norm(tgt - pos)
        up_perp = up - (up @ fwd) * fwd
        up_perp /= np.linalg.norm(up_perp)
        eps = 0.01 * np.linalg.norm(tgt - pos)
        s, l = CAM.project(to_camera_frame(R, pos, tgt + eps * up_perp))
        assert l < CAM.cy - 1.0 and s == pytest.approx(CAM.cx, abs=1e-6)
        right = np.cross(fwd, up_perp)
        s, l = CAM.project(to_camera_frame(R, pos, tgt + eps * right))
        assert s > CAM.cx + 1.0 and l == pytest.approx(CAM.cy, abs=1e-6)


def test_look_at_concrete_case():
    # camera on +x looking at the origin, render +z up: boresight -x, image down = -z, image right = +y
    M = look_at([10.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 1.0]).as_matrix()
    np.testing.assert_allclose(M[:, 2], [-1, 0, 0], atol=1e-15)
    np.testing.assert_allclose(M[:, 1], [0, 0, -1], atol=1e-15)
    np.testing.assert_allclose(M[:, 0], [0, 1, 0], atol=1e-15)


def test_look_at_errors():
    with pytest.raises(UserError, match="coincides"):
        look_at([1, 2, 3], [1, 2, 3])
    with pytest.raises(UserError, match="parallel"):
        look_at([0, 0, 10], [0, 0, 0], [0, 0, 1])
    with pytest.raises(UserError, match="position"):
        look_at([0, np.nan, 10], [0, 0, 0])


def test_quaternion_round_trip_and_order():
    rng = np.random.default_rng(2)
    Rs = Rotation.random(200, random_state=rng)
    q = quat_xyzw(Rs)
    assert q.shape == (200, 4) and np.all(q[:, 3] >= 0)
    back = rotation_from_quat_xyzw(q)
    assert np.max((back * Rs.inv()).magnitude()) < 1e-12
    for R in Rs[:20]:
        assert (rotation_from_quat_xyzw(quat_xyzw(R)) * R.inv()).magnitude() < 1e-12
    # scalar-last: 90 deg about +z
    np.testing.assert_allclose(quat_xyzw(axis_angle([0, 0, 1], math.pi / 2)),
                               [0, 0, math.sqrt(0.5), math.sqrt(0.5)], atol=1e-15)
    # a matrix works too, and non-unit quaternions are normalized
    np.testing.assert_allclose(quat_xyzw(np.eye(3)), [0, 0, 0, 1])
    np.testing.assert_allclose(rotation_from_quat_xyzw([0, 0, 0, 2.5]).as_matrix(), np.eye(3))


@pytest.mark.parametrize("bad", [[0, 0, 0, 0], [np.nan, 0, 0, 1], [0, 0, 1], [[[0, 0, 0, 1]]], ["a", 0, 0, 1],
                                 [np.inf, 0, 0, 1]])
def test_bad_quaternions_raise(bad):
    with pytest.raises(UserError):
        rotation_from_quat_xyzw(bad, name="pose.quat_render_from_cam_xyzw")


def test_manifest_pose_convention():
    # p_render = R(quat) @ p_cam + position, and to_camera_frame inverts it (eq. 1)
    rng = np.random.default_rng(3)
    R = Rotation.random(random_state=rng)
    pos = rng.normal(size=3)
    q = quat_xyzw(R)
    p_cam = rng.normal(size=(10, 3))
    p_render = transform_points(rotation_from_quat_xyzw(q), pos, p_cam)
    np.testing.assert_allclose(p_render, (R.as_matrix() @ p_cam.T).T + pos, atol=1e-12)
    np.testing.assert_allclose(to_camera_frame(R, pos, p_render), p_cam, atol=1e-12)
    Rinv, tinv = invert_transform(R, pos)
    np.testing.assert_allclose(transform_points(Rinv, tinv, p_render), p_cam, atol=1e-12)
    np.testing.assert_allclose(transform_points(R.as_matrix(), pos, p_cam), p_render, atol=1e-12)


def test_skew_and_axis_angle():
    rng = np.random.default_rng(4)
    v, w = rng.normal(size=(2, 3))
    np.testing.assert_allclose(skew(v) @ w, np.cross(v, w), atol=1e-14)
    V = rng.normal(size=(5, 3))
    np.testing.assert_allclose(np.einsum("nij,j->ni", skew(V), w), np.cross(V, w), atol=1e-14)
    axis = np.array([1.0, 2.0, -2.0])
    R = axis_angle(axis, 0.7)
    a, ang = as_axis_angle(R)
    np.testing.assert_allclose(a, axis / 3.0, atol=1e-14)
    assert ang == pytest.approx(0.7)
    # small-angle rotation ~ I + skew(theta)
    th = np.array([1e-7, -2e-7, 3e-7])
    np.testing.assert_allclose(Rotation.from_rotvec(th).as_matrix(), np.eye(3) + skew(th), atol=1e-13)
    with pytest.raises(UserError):
        axis_angle([0, 0, 0], 1.0)


def test_rotation_from_matrix_and_angle_between():
    R = Rotation.random(random_state=np.random.default_rng(5)).as_matrix()
    assert np.allclose(rotation_from_matrix(R).as_matrix(), R)
    with pytest.raises(UserError, match="proper rotation"):
        rotation_from_matrix(np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(UserError):
        rotation_from_matrix(np.eye(2))
    assert angle_between([1, 0, 0], [0, 1, 0]) == pytest.approx(math.pi / 2)
    assert angle_between([1, 0, 0], [1, 1e-9, 0]) == pytest.approx(1e-9, rel=1e-6)
