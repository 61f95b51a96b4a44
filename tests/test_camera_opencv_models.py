"""OpenCV's full distortion model (rational, thin prism, tilt) and the Kannala-Brandt fisheye against OpenCV.

Each model is checked against ``cv2.projectPoints`` / ``cv2.fisheye.projectPoints`` to 1e-9 px on seeded random
coefficient sets, for its round trip ``project(unproject(px))`` to 1e-9 px over the whole image, and for its
analytic Jacobians against central differences.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from renderlab.errors import UserError
from renderlab.geometry import CameraModel
from renderlab.geometry.calibration import opencv_intrinsics
from renderlab.geometry.distortion import distort, distortion_jacobian
from renderlab.geometry.distortion_opencv import KEYS, tilt_matrix

PX_TOL = 1e-9  # px: against OpenCV and for the round trip
N_SETS = 12  # seeded random coefficient sets per vector length


def _opencv_coeffs(rng: np.random.Generator, n: int) -> dict[str, float]:
    """Random coefficients of an n-vector, of the size real calibrations have."""
    v = np.zeros(14)
    v[:5] = [rng.uniform(-0.3, 0.1), rng.uniform(-0.05, 0.15), rng.uniform(-2e-3, 2e-3),
             rng.uniform(-2e-3, 2e-3), rng.uniform(-0.02, 0.02)]
    if n >= 8:
        v[5:8] = [rng.uniform(-0.1, 0.2), rng.uniform(-0.03, 0.05), rng.uniform(-0.01, 0.01)]
    if n >= 12:
        v[8:12] = rng.uniform(-2e-3, 2e-3, 4)
    if n >= 14:
        v[12:14] = rng.uniform(-0.03, 0.03, 2)  # radians (about 1.7 deg)
    return dict(zip(KEYS, v.tolist()))


def _opencv_camera(rng: np.random.Generator, n: int) -> CameraModel:
    """A 640x480 camera with a random n-vector whose whole image (and a 40 px margin) is on the unfolded
    branch: sets that fold inside the image (no real calibration does) are drawn again."""
    margin = np.array([[-40.0, -40.0], [680.0, -40.0], [-40.0, 520.0], [680.0, 520.0], [320.0, -40.0],
                       [-40.0, 240.0]])
    for _ in range(100):
        cam = CameraModel(640, 480, rng.uniform(420, 560), rng.uniform(420, 560), rng.uniform(300, 340),
                          rng.uniform(220, 260), model="opencv", distortion=_opencv_coeffs(rng, n))
        if cam.unproject(margin, return_converged=True)[1].all():
            return cam
    raise AssertionError("no unfolded coefficient set drawn")


def _rays_in_view(cam: CameraModel, rng: np.random.Generator, n: int = 3000) -> np.ndarray:
    """Points in front of the camera at random ranges whose pixels are near or in the image."""
    sl = np.column_stack([rng.uniform(-40, cam.width + 40, n), rng.uniform(-40, cam.height + 40, n)])
    rays = cam.unproject(sl)
    rays = rays[np.isfinite(rays).all(axis=1)]
    assert len(rays) > 0.9 * n
    return rays * rng.uniform(0.5, 50.0, (len(rays), 1))


def _cv_project(cam: CameraModel, pts: np.ndarray) -> np.ndarray:
    K, D, fisheye = opencv_intrinsics(cam)
    if fisheye:
        out, _ = cv2.fisheye.projectPoints(pts.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, D,
                                           alpha=cam.skew / cam.fx)
    else:
        out, _ = cv2.projectPoints(pts.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, D)
    return out.reshape(-1, 2)


def _central_jacobian(f, p: np.ndarray, h: float) -> np.ndarray:
    cols = [(f(p + h * e) - f(p - h * e)) / (2 * h) for e in np.eye(p.shape[-1])]
    return np.stack(cols, axis=-1)


# ------------------------------------------------------------------ OpenCV full model vs cv2.projectPoints
@pytest.mark.parametrize("n", [8, 12, 14])
def test_opencv_model_matches_cv2_project_points(n):
    rng = np.random.default_rng(100 + n)
    worst = 0.0
    for _ in range(N_SETS):
        cam = _opencv_camera(rng, n)
        _, D, _ = opencv_intrinsics(cam)
        np.testing.assert_array_equal(D[n:], 0.0)
        pts = _rays_in_view(cam, rng)
        ours = cam.project(pts)
        assert np.isfinite(ours).all()
        ref, _ = cv2.projectPoints(pts.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), cam.K_matrix, D[:n])
        worst = max(worst, float(np.abs(ours - ref.reshape(-1, 2)).max()))
    assert worst <= PX_TOL, worst


def test_opencv_model_without_extra_terms_is_brown_bit_for_bit():
    rng = np.random.default_rng(7)
    brown = {"k1": -0.27, "k2": 0.09, "k3": -0.012, "p1": 7e-4, "p2": -4e-4}
    u = rng.uniform(-0.8, 0.8, (500, 2))
    np.testing.assert_array_equal(distort("opencv", {**dict.fromkeys(KEYS, 0.0), **brown}, u),
                                  distort("brown", brown, u))
    np.testing.assert_array_equal(distortion_jacobian("opencv", {**dict.fromkeys(KEYS, 0.0), **brown}, u),
                                  distortion_jacobian("brown", brown, u))


def test_tilt_matrix_identity_and_small_angle_form():
    np.testing.assert_array_equal(tilt_matrix(0.0, 0.0), np.eye(3))
    m = tilt_matrix(1e-4, -2e-4)  # to first order the homography's last row is (sin tau_y, -sin tau_x, 1)
    np.testing.assert_allclose(m[2], [-2e-4, -1e-4, 1.0], atol=1e-7)
    np.testing.assert_allclose(m[:2, :2], np.eye(2), atol=1e-7)


@pytest.mark.parametrize("n", [8, 12, 14])
def test_opencv_round_trip_over_the_whole_image(n):
    rng = np.random.default_rng(200 + n)
    for _ in range(N_SETS):
        cam = _opencv_camera(rng, n)
        grid = cam.pixel_grid()[::7, ::7].reshape(-1, 2)
        corners = np.array([[-0.5, -0.5], [cam.width - 0.5, -0.5], [-0.5, cam.height - 0.5],
                            [cam.width - 0.5, cam.height - 0.5]])
        sl = np.vstack([grid, corners, rng.uniform([-0.5, -0.5], [cam.width - 0.5, cam.height - 0.5], (800, 2))])
        rays, ok = cam.unproject(sl, return_converged=True)
        assert ok.all()
        assert np.abs(cam.project(rays) - sl).max() <= PX_TOL


@pytest.mark.parametrize("n", [8, 14])
def test_opencv_jacobians_match_central_differences(n):
    rng = np.random.default_rng(300 + n)
    for _ in range(4):
        cam = _opencv_camera(rng, n)
        u = rng.uniform(-0.7, 0.7, (400, 2))
        J = distortion_jacobian("opencv", cam.distortion, u)
        Jn = _central_jacobian(lambda v, cam=cam: distort("opencv", cam.distortion, v), u, 1e-6)
        np.testing.assert_allclose(J, Jn, atol=2e-9)
        pts = _rays_in_view(cam, rng, 400)
        Jp = cam.project_jacobian(pts)
        Jpn = _central_jacobian(cam.project, pts, 1e-6 * np.linalg.norm(pts, axis=1, keepdims=True).mean())
        scale = np.abs(Jp).max(axis=(1, 2), keepdims=True)
        assert np.abs(Jp - Jpn).max(axis=(1, 2)).max() <= 1e-7 * scale.max()


def test_opencv_pole_and_fold_are_outside_the_valid_field():
    # denominator 1 + k4 r^2 vanishes at r = 1: the valid radius stops before it, and projection there is NaN
    cam = CameraModel(640, 480, 400.0, 400.0, 319.5, 239.5, model="opencv", distortion={"k4": -1.0})
    assert cam.max_radius < 1.0
    assert np.isnan(cam.project(np.array([1.0, 0.0, 1.0]))).all()
    assert np.isfinite(cam.project(np.array([0.5 * cam.max_radius, 0.0, 1.0]))).all()


# ------------------------------------------------------------------ Kannala-Brandt fisheye vs cv2.fisheye
def _fisheye_coeffs(rng: np.random.Generator) -> dict[str, float]:
    return {"k1": rng.uniform(-0.05, 0.1), "k2": rng.uniform(-0.03, 0.03), "k3": rng.uniform(-0.01, 0.01),
            "k4": rng.uniform(-2e-3, 2e-3)}


def _wide_rays(rng: np.random.Generator, max_deg: float, n: int = 3000) -> np.ndarray:
    theta = np.radians(max_deg) * np.sqrt(rng.uniform(0, 1, n))
    phi = rng.uniform(0, 2 * np.pi, n)
    d = np.column_stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)])
    return d * rng.uniform(0.5, 50.0, (n, 1))


@pytest.mark.parametrize("alpha", [0.0, 2e-3])
def test_fisheye_matches_cv2_fisheye_project_points(alpha):
    rng = np.random.default_rng(400 + int(alpha * 1e3))
    worst = 0.0
    for _ in range(N_SETS):
        fx = rng.uniform(250, 350)
        cam = CameraModel(1024, 1024, fx, fx * rng.uniform(0.98, 1.02), rng.uniform(500, 524),
                          rng.uniform(500, 524), skew=alpha * fx, model="kannala_brandt",
                          distortion=_fisheye_coeffs(rng))
        pts = np.vstack([_wide_rays(rng, 85.0), [[0.0, 0.0, 3.0], [1e-9, -2e-9, 1.0]]])  # axis, r < 1e-8
        pts = pts[np.hypot(pts[:, 0], pts[:, 1]) / pts[:, 2] < cam.max_radius]  # before a fold (NaN there)
        ours = cam.project(pts)
        assert len(pts) > 2000 and np.isfinite(ours).all()
        worst = max(worst, float(np.abs(ours - _cv_project(cam, pts)).max()))
    assert worst <= PX_TOL, worst


def test_fisheye_round_trip_and_unproject_to_wide_angles():
    rng = np.random.default_rng(500)
    for _ in range(N_SETS):
        c = _fisheye_coeffs(rng)
        cam = CameraModel(800, 800, 300.0, 300.0, 399.5, 399.5, model="kannala_brandt", distortion=c)
        sl = np.vstack([cam.pixel_grid()[::9, ::9].reshape(-1, 2), [[399.5, 399.5]]])
        rays, ok = cam.unproject(sl, return_converged=True)
        # every pixel inside the image of the 87 deg cone has a ray (the corners lie beyond 90 deg: none)
        t = math.radians(87.0)
        r_d87 = t * (1 + c["k1"] * t ** 2 + c["k2"] * t ** 4 + c["k3"] * t ** 6 + c["k4"] * t ** 8)
        inside = np.hypot(*((sl - 399.5) / 300.0).T) < r_d87
        assert ok[inside].all() and inside.mean() > 0.4
        assert np.degrees(np.arccos(rays[ok, 2])).max() > 80.0
        assert np.abs(cam.project(rays[ok]) - sl[ok]).max() <= PX_TOL
        d = _wide_rays(rng, 84.0, 500)
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        sl_d = cam.project(d)
        valid = np.hypot(d[:, 0], d[:, 1]) / d[:, 2] < cam.max_radius  # NaN only beyond a fold
        assert np.isfinite(sl_d[valid]).all() and np.isnan(sl_d[~valid]).all()
        assert np.abs(cam.unproject(sl_d[valid]) - d[valid]).max() < 1e-11


def test_fisheye_jacobians_match_central_differences_and_the_axis_limit():
    rng = np.random.default_rng(600)
    c = _fisheye_coeffs(rng)
    u = np.vstack([rng.uniform(-3, 3, (400, 2)), rng.uniform(-1e-3, 1e-3, (50, 2))])
    J = distortion_jacobian("kannala_brandt", c, u)
    Jn = _central_jacobian(lambda v: distort("kannala_brandt", c, v), u, 1e-7)
    np.testing.assert_allclose(J, Jn, atol=2e-8)
    np.testing.assert_array_equal(distortion_jacobian("kannala_brandt", c, np.zeros(2)), np.eye(2))
    np.testing.assert_allclose(distortion_jacobian("kannala_brandt", c, np.array([2e-8, 0.0])), np.eye(2),
                               atol=1e-15)
    cam = CameraModel(640, 480, 300.0, 300.0, 319.5, 239.5, model="kannala_brandt", distortion=c)
    pts = _wide_rays(rng, 80.0, 300)
    Jp = cam.project_jacobian(pts)
    Jpn = _central_jacobian(cam.project, pts, 1e-6)
    assert np.abs(Jp - Jpn).max() <= 1e-6 * np.abs(Jp).max()


def test_fisheye_fold_is_refused():
    # theta_d = theta (1 - 0.5 theta^2) peaks at theta = sqrt(2/3) (46.8 deg): beyond it project is NaN
    cam = CameraModel(640, 480, 300.0, 300.0, 319.5, 239.5, model="kannala_brandt", distortion={"k1": -0.5})
    assert cam.max_radius == pytest.approx(math.tan(math.sqrt(2 / 3)), rel=1e-2)
    assert np.isnan(cam.project(np.array([math.tan(0.85), 0.0, 1.0]))).all()
    assert np.isfinite(cam.project(np.array([math.tan(0.78), 0.0, 1.0]))).all()


def test_new_models_validate_their_keys():
    with pytest.raises(UserError, match="camera.distortion.e1"):
        CameraModel(64, 48, 50.0, 50.0, 31.5, 23.5, model="opencv", distortion={"e1": 0.1})
    with pytest.raises(UserError, match=r"camera.distortion.k5: unknown coefficient for model 'kannala_brandt'"):
        CameraModel(64, 48, 50.0, 50.0, 31.5, 23.5, model="kannala_brandt", distortion={"k5": 0.1})
    cam = CameraModel(64, 48, 50.0, 50.0, 31.5, 23.5, model="opencv", distortion={"tau_x": 0.01})
    assert tuple(cam.distortion) == KEYS and cam.to_dict()["distortion"]["tau_x"] == 0.01


# ------------------------------------------------------------------ property: the round trip holds for any mild set
@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-1.0, 1.0), min_size=14, max_size=14), st.floats(-1.0, 1.0), st.integers(0, 2 ** 32 - 1))
def test_opencv_round_trip_property(unit, skew_unit, seed):
    scale = np.array([0.3, 0.1, 2e-3, 2e-3, 0.03, 0.2, 0.05, 0.01, 2e-3, 2e-3, 2e-3, 2e-3, 0.03, 0.03])
    cam = CameraModel(320, 240, 240.0, 236.0, 161.0, 118.0, skew=2.0 * skew_unit, model="opencv",
                      distortion=dict(zip(KEYS, (np.array(unit) * scale).tolist())))
    corners = np.array([[-0.5, -0.5], [319.5, -0.5], [-0.5, 239.5], [319.5, 239.5], [161.0, -0.5], [-0.5, 118.0]])
    assume(cam.unproject(corners, return_converged=True)[1].all())  # sets that fold inside the image: no preimage
    sl = np.random.default_rng(seed).uniform([-0.5, -0.5], [319.5, 239.5], (200, 2))
    rays, ok = cam.unproject(sl, return_converged=True)
    assert ok.all()
    assert np.abs(cam.project(rays) - sl).max() <= PX_TOL
