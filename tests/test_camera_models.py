"""CameraModel: projection vs OpenCV, exact inverse, Jacobians, Owen model, validation."""

from __future__ import annotations

import dataclasses
import json
import math

import cv2
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from renderlab.errors import UserError
from renderlab.geometry import CameraModel, owen_coefficients_from_mm
from renderlab.geometry.distortion import distort, distortion_jacobian, undistort

BROWN = {"k1": -0.25, "k2": 0.08, "k3": -0.01, "p1": 8e-4, "p2": -6e-4}
OWEN = {"e1": 2e-4, "e2": -0.06, "e3": 1.5e-4, "e4": 0.012, "e5": -3e-4, "e6": 4e-4}

CAMERAS = {
    "pinhole": CameraModel(640, 480, 800.0, 760.0, 330.2, 235.9, skew=1.5, skew_yx=-0.8),
    "brown": CameraModel(1024, 768, 900.0, 870.0, 520.4, 371.3, skew=2.0, skew_yx=0.7, model="brown",
                         distortion=BROWN),
    "brown_wide": CameraModel(1280, 960, 640.0, 650.0, 645.0, 470.0, model="brown",
                              distortion={"k1": -0.3, "k2": 0.1, "k3": -0.012, "p1": 1e-3, "p2": 5e-4}),
    "owen": CameraModel(1024, 1024, 1100.0, 1080.0, 515.0, 505.5, skew=-1.2, skew_yx=0.9, model="owen",
                        distortion=OWEN),
}


def _image_samples(cam: CameraModel, rng: np.random.Generator, n: int = 4000) -> np.ndarray:
    """Random pixels over the whole image plus the exact corners and edge midpoints."""
    W, H = cam.width, cam.height
    s = rng.uniform(-0.5, W - 0.5, n)
    l = rng.uniform(-0.5, H - 0.5, n)
    edges = [(-0.5, -0.5), (W - 0.5, -0.5), (-0.5, H - 0.5), (W - 0.5, H - 0.5),
             (0, 0), (W - 1, 0), (0, H - 1), (W - 1, H - 1),
             ((W - 1) / 2, -0.5), ((W - 1) / 2, H - 0.5), (-0.5, (H - 1) / 2), (W - 0.5, (H - 1) / 2)]
    return np.vstack([np.column_stack([s, l]), np.array(edges, dtype=float)])


def _points_in_view(cam: CameraModel, rng: np.random.Generator, n: int = 2000) -> np.ndarray:
    rays = cam.unproject(_image_samples(cam, rng, n))
    return rays * rng.uniform(0.5, 50.0, (len(rays), 1))


def _cv2_project(cam: CameraModel, p: np.ndarray) -> np.ndarray:
    d = cam.distortion
    dist = np.array([d.get("k1", 0), d.get("k2", 0), d.get("p1", 0), d.get("p2", 0), d.get("k3", 0)], float)
    out, _ = cv2.projectPoints(p.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), cam.K_matrix, dist)
    return out.reshape(-1, 2)


# --------------------------------------------------------------------------- OpenCV agreement
def test_pinhole_matches_cv2_zero_distortion():
    cam = CameraModel(800, 600, 750.0, 720.0, 401.3, 298.2)
    rng = np.random.default_rng(1)
    p = np.column_stack([rng.uniform(-2, 2, 3000), rng.uniform(-2, 2, 3000), rng.uniform(0.5, 10, 3000)])
    assert np.max(np.abs(cam.project(p) - _cv2_project(cam, p))) <= 1e-6
    # and by hand: s = fx x/z + cx
    np.testing.assert_allclose(cam.project(p)[:, 0], 750.0 * p[:, 0] / p[:, 2] + 401.3, rtol=0, atol=1e-9)


def test_brown_matches_cv2_random_coefficients():
    rng = np.random.default_rng(20240601)
    worst, checked = 0.0, 0
    for _ in range(40):
        dist = {"k1": rng.uniform(-0.4, 0.4), "k2": rng.uniform(-0.15, 0.15), "k3": rng.uniform(-0.05, 0.05),
                "p1": rng.uniform(-2e-3, 2e-3), "p2": rng.uniform(-2e-3, 2e-3)}
        W, H = int(rng.integers(64, 2048)), int(rng.integers(64, 2048))
        f = rng.uniform(0.6, 2.5) * max(W, H)
        cam = CameraModel(W, H, f, f * rng.uniform(0.95, 1.05), rng.uniform(0.4, 0.6) * W,
                          rng.uniform(0.4, 0.6) * H, skew=0.0, model="brown", distortion=dist)
        x = rng.uniform(-0.6, 0.6, (500, 2)) * np.array([W, H]) / f
        z = rng.uniform(0.1, 1e3, 500)
        p = np.column_stack([x * z[:, None], z])
        sl = cam.project(p)
        inside = np.hypot(x[:, 0], x[:, 1]) < cam.max_radius  # before the fold (see test below)
        assert np.isfinite(sl[inside]).all() and np.isnan(sl[~inside]).all()
        checked += int(inside.sum())
        worst = max(worst, float(np.max(np.abs(sl[inside] - _cv2_project(cam, p[inside])))))
    assert checked > 0.9 * 40 * 500
    assert worst <= 1e-6, worst


def test_projection_beyond_the_fold_is_nan():
    # r (1 + k1 r^2) with k1 = -0.3 folds over at r = 1/sqrt(0.9); OpenCV keeps mapping points beyond it
    cam = CameraModel(1000, 1000, 500.0, 500.0, 499.5, 499.5, model="brown", distortion={"k1": -0.3})
    r_fold = 1.0 / math.sqrt(0.9)
    assert r_fold * 0.99 < cam.max_radius < r_fold
    p = np.array([[0.5, 0.0, 1.0], [1.5, 0.0, 1.0], [0.0, -2.0, 1.0], [1.0, 0.0, 1.0]])
    sl = cam.project(p)
    assert np.isfinite(sl[[0, 3]]).all() and np.isnan(sl[1:3]).all()
    assert np.isnan(cam.project_jacobian(p)[1:3]).all()
    ref = _cv2_project(cam, p)
    assert np.isfinite(ref).all() and cam.in_image(ref[2])  # cv2 folds (0, -2) back into the image
    assert CAMERAS["pinhole"].max_radius == math.inf
    assert CAMERAS["brown"].max_radius > 1.0 and CAMERAS["owen"].max_radius > 1.0


# --------------------------------------------------------------------------- exact inverse
@pytest.mark.parametrize("name", list(CAMERAS))
def test_pixel_round_trip_whole_image(name):
    cam = CAMERAS[name]
    sl = _image_samples(cam, np.random.default_rng(7))
    rays, ok = cam.unproject(sl, return_converged=True)
    assert ok.all()
    np.testing.assert_allclose(np.linalg.norm(rays, axis=1), 1.0, rtol=0, atol=1e-15)
    assert np.all(rays[:, 2] > 0)
    err = np.max(np.abs(cam.project(rays) - sl))
    assert err <= 1e-9, err


@pytest.mark.parametrize("name", list(CAMERAS))
def test_full_pixel_grid_round_trip(name):
    cam = CAMERAS[name]
    grid = cam.pixel_grid()
    rays = cam.unproject(grid)  # (H, W, 3)
    assert rays.shape == (cam.height, cam.width, 3)
    assert np.max(np.abs(cam.project(rays) - grid)) <= 1e-9


@pytest.mark.parametrize("name", list(CAMERAS))
def test_ray_round_trip_parallel(name):
    cam = CAMERAS[name]
    p = _points_in_view(cam, np.random.default_rng(3))
    back = cam.unproject(cam.project(p))
    cos = np.sum(back * p, axis=1) / np.linalg.norm(p, axis=1)
    sin = np.linalg.norm(np.cross(back, p), axis=1) / np.linalg.norm(p, axis=1)
    assert np.all(cos > 0)
    assert np.max(sin) <= 1e-12


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    model=st.sampled_from(["brown", "owen"]),
    c=st.lists(st.floats(-1.0, 1.0), min_size=6, max_size=6),
    fx=st.floats(1200.0, 4000.0), aspect=st.floats(0.9, 1.1),
    skew=st.floats(-3.0, 3.0), skew_yx=st.floats(-3.0, 3.0),
    cx_off=st.floats(-30.0, 30.0), cy_off=st.floats(-30.0, 30.0),
)
def test_round_trip_hypothesis(model, c, fx, aspect, skew, skew_yx, cx_off, cy_off):
    W, H = 1024, 800
    if model == "brown":
        dist = {"k1": 0.3 * c[0], "k2": 0.08 * c[1], "k3": 0.02 * c[2], "p1": 1e-3 * c[3], "p2": 1e-3 * c[4]}
    else:
        dist = {"e1": 5e-4 * c[0], "e2": 0.08 * c[1], "e3": 5e-4 * c[2], "e4": 0.02 * c[3],
                "e5": 1e-3 * c[4], "e6": 1e-3 * c[5]}
    cam = CameraModel(W, H, fx, fx * aspect, (W - 1) / 2 + cx_off, (H - 1) / 2 + cy_off,
                      skew=skew, skew_yx=skew_yx, model=model, distortion=dist)
    sl = _image_samples(cam, np.random.default_rng(0), 300)
    rays, ok = cam.unproject(sl, return_converged=True)
    assert ok.all()
    assert np.max(np.abs(cam.project(rays) - sl)) <= 1e-9


def test_undistort_converges_tightly_in_normalized_coordinates():
    rng = np.random.default_rng(11)
    u_true = rng.uniform(-0.6, 0.6, (5000, 2))
    for model, coeffs in (("brown", BROWN), ("owen", OWEN)):
        ud = distort(model, coeffs, u_true)
        u, ok = undistort(model, coeffs, ud)
        assert ok.all()
        assert np.max(np.abs(distort(model, coeffs, u) - ud)) <= 1e-14
        assert np.max(np.abs(u - u_true)) <= 1e-13


def test_undistort_flags_points_without_a_preimage():
    # r (1 - 0.5 r^2) peaks at 0.544: distorted radii beyond it have no inverse
    coeffs = {"k1": -0.5, "k2": 0.0, "k3": 0.0, "p1": 0.0, "p2": 0.0}
    ud = np.array([[0.2, 0.1], [0.8, 0.0], [np.nan, 0.0], [0.0, 0.3]])
    u, ok = undistort("brown", coeffs, ud, max_iter=40)
    assert ok.tolist() == [True, False, False, True]
    assert np.all(np.isnan(u[~ok])) and np.all(np.isfinite(u[ok]))
    cam = CameraModel(100, 100, 50.0, 50.0, 49.5, 49.5, model="brown", distortion=coeffs)
    rays, ok2 = cam.unproject(np.array([[49.5 + 50 * 0.8, 49.5], [60.0, 40.0]]), return_converged=True)
    assert ok2.tolist() == [False, True]
    assert np.all(np.isnan(rays[0])) and np.all(np.isfinite(rays[1]))


# --------------------------------------------------------------------------- behind the camera, shapes
def test_points_behind_camera_are_nan():
    cam = CAMERAS["brown"]
    p = np.array([[0.1, 0.2, 1.0], [0.1, 0.2, 0.0], [0.1, 0.2, -1.0], [0.0, 0.0, -1e-300], [1.0, 1.0, 5.0]])
    sl = cam.project(p)
    assert sl.shape == (5, 2) and sl.dtype == np.float64
    assert np.isfinite(sl[[0, 4]]).all()
    assert np.isnan(sl[1:4]).all()
    J = cam.project_jacobian(p)
    assert np.isnan(J[1:4]).all() and np.isfinite(J[[0, 4]]).all()


def test_shapes():
    cam = CAMERAS["owen"]
    assert cam.project([0.0, 0.0, 1.0]).shape == (2,)
    np.testing.assert_allclose(cam.project([0.0, 0.0, 1.0]), [cam.cx, cam.cy], atol=1e-12)
    assert cam.project(np.zeros((4, 5, 3)) + [0, 0, 1]).shape == (4, 5, 2)
    assert cam.unproject([cam.cx, cam.cy]).shape == (3,)
    np.testing.assert_allclose(cam.unproject([cam.cx, cam.cy]), [0, 0, 1], atol=1e-15)
    assert cam.project_jacobian([0.1, 0.0, 2.0]).shape == (2, 3)
    assert cam.distortion_jacobian([0.1, 0.2]).shape == (2, 2)


# --------------------------------------------------------------------------- Jacobians
def _fd_project(cam, p, h=1e-6):
    J = np.zeros(p.shape[:-1] + (2, 3))
    for k in range(3):
        dp = np.zeros(3)
        dp[k] = h * np.abs(p[..., 2]).mean()
        J[..., :, k] = (cam.project(p + dp) - cam.project(p - dp)) / (2 * dp[k])
    return J


@pytest.mark.parametrize("name", list(CAMERAS))
def test_project_jacobian_matches_finite_differences(name):
    cam = CAMERAS[name]
    p = _points_in_view(cam, np.random.default_rng(5), 300)
    p = p / p[:, 2:3] * np.random.default_rng(6).uniform(1.0, 3.0, (len(p), 1))
    J = cam.project_jacobian(p)
    Jfd = _fd_project(cam, p)
    scale = np.max(np.abs(J), axis=(1, 2), keepdims=True)
    assert np.max(np.abs(J - Jfd) / scale) <= 1e-6


@pytest.mark.parametrize("model,coeffs", [("pinhole", {}), ("brown", BROWN), ("owen", OWEN)])
def test_distortion_jacobian_matches_finite_differences(model, coeffs):
    rng = np.random.default_rng(9)
    u = np.vstack([rng.uniform(-0.7, 0.7, (2000, 2)), [[1e-3, -2e-3], [0.5, 0.0], [0.0, -0.5]]])
    J = distortion_jacobian(model, coeffs, u)
    h = 1e-6
    Jfd = np.stack([(distort(model, coeffs, u + [h, 0]) - distort(model, coeffs, u - [h, 0])) / (2 * h),
                    (distort(model, coeffs, u + [0, h]) - distort(model, coeffs, u - [0, h])) / (2 * h)], axis=-1)
    assert np.max(np.abs(J - Jfd) / np.max(np.abs(J), axis=(1, 2), keepdims=True)) <= 1e-6


def test_owen_jacobian_finite_at_origin():
    J = distortion_jacobian("owen", OWEN, np.zeros(2))
    # at r = 0 only the tip/tilt terms survive to first order: d(e5 y x + e6 x x)/dx = 0 at 0
    np.testing.assert_allclose(J, np.eye(2), atol=0)


# --------------------------------------------------------------------------- Owen model
def _owen_direct(e, x, y):
    """Owen (2011) distortion evaluated term by term, scalar Python floats."""
    r = math.hypot(x, y)
    radial = e["e2"] * r**2 + e["e4"] * r**4           # radial
    tilt = e["e5"] * y + e["e6"] * x                    # tip/tilt/prism
    pinwheel = e["e1"] * r + e["e3"] * r**3             # pinwheel
    dx = (radial + tilt) * x + pinwheel * (-y)
    dy = (radial + tilt) * y + pinwheel * x
    return x + dx, y + dy


def test_owen_matches_direct_evaluation():
    cam = CAMERAS["owen"]
    rng = np.random.default_rng(12)
    p = np.column_stack([rng.uniform(-0.5, 0.5, 400), rng.uniform(-0.5, 0.5, 400), np.ones(400)])
    p *= rng.uniform(1, 100, (400, 1))
    sl = cam.project(p)
    for (x, y, z), (s, l) in zip(p, sl):
        xd, yd = _owen_direct(OWEN, x / z, y / z)
        s_ref = cam.fx * xd + cam.skew * yd + cam.cx
        l_ref = cam.skew_yx * xd + cam.fy * yd + cam.cy
        assert abs(s - s_ref) <= 1e-9 and abs(l - l_ref) <= 1e-9


def test_owen_millimetre_coefficients_and_retina_pixel_map():
    """A camera given GIANT/Retina-style (f in mm, K in px/mm, e_n for mm coordinates) equals the
    normalized-unit model after owen_coefficients_from_mm."""
    f = 29.0                                    # mm
    Kx, Kxy, Kyx, Ky = 71.4, 0.05, -0.03, 71.2  # px/mm
    s0, l0 = 511.2, 514.9
    e_mm = {"e1": 1e-6, "e2": -4e-5, "e3": 2e-9, "e4": 3e-9, "e5": -1e-5, "e6": 2e-5}
    cam = CameraModel.from_retina(f, Kx, Kxy, Kyx, Ky, s0, l0, 1024, 1024, model="owen",
                                  distortion=owen_coefficients_from_mm(e_mm, f))
    assert cam.fx == pytest.approx(f * Kx) and cam.skew == pytest.approx(f * Kxy)
    assert cam.skew_yx == pytest.approx(f * Kyx) and cam.fy == pytest.approx(f * Ky)
    rng = np.random.default_rng(4)
    for _ in range(200):
        p = np.array([rng.uniform(-0.25, 0.25), rng.uniform(-0.25, 0.25), 1.0]) * rng.uniform(1, 10)
        xf, yf = _owen_direct(e_mm, f * p[0] / p[2], f * p[1] / p[2])  # focal plane, mm
        ref = np.array([Kx * xf + Kxy * yf + s0, Kyx * xf + Ky * yf + l0])
        np.testing.assert_allclose(cam.project(p), ref, rtol=0, atol=1e-9)


# --------------------------------------------------------------------------- construction helpers
def test_K_matrix_and_pixel_map():
    cam = CAMERAS["pinhole"]
    K = cam.K_matrix
    np.testing.assert_array_equal(K, [[800.0, 1.5, 330.2], [-0.8, 760.0, 235.9], [0, 0, 1]])
    p = np.array([0.3, -0.2, 2.0])
    h = K @ (p / p[2])
    np.testing.assert_allclose(cam.project(p), h[:2], atol=1e-12)


def test_from_fov():
    cam = CameraModel.from_fov(1000, 500, 60.0)
    assert cam.fx == pytest.approx(500.0 / math.tan(math.radians(30.0)))
    assert cam.fy == cam.fx and (cam.cx, cam.cy) == (499.5, 249.5)
    left, right = cam.unproject([[-0.5, 249.5], [999.5, 249.5]])
    assert math.degrees(math.acos(left @ right)) == pytest.approx(60.0, abs=1e-12)
    cam2 = CameraModel.from_fov(1000, 500, 60.0, 40.0)
    top, bottom = cam2.unproject([[499.5, -0.5], [499.5, 499.5]])
    assert math.degrees(math.acos(top @ bottom)) == pytest.approx(40.0, abs=1e-12)
    with pytest.raises(UserError, match="fov_x_deg"):
        CameraModel.from_fov(100, 100, 180.0)


def test_in_image_and_pixel_grid():
    cam = CameraModel(4, 3, 10.0, 10.0, 1.5, 1.0)
    g = cam.pixel_grid()
    assert g.shape == (3, 4, 2) and g.dtype == np.float64
    assert tuple(g[0, 0]) == (0.0, 0.0) and tuple(g[2, 3]) == (3.0, 2.0) and tuple(g[1, 2]) == (2.0, 1.0)
    assert cam.in_image(g).all()
    pts = np.array([[-0.5, -0.5], [3.49, 2.49], [3.5, 1.0], [1.0, 2.5], [-0.51, 0.0], [np.nan, 1.0]])
    assert cam.in_image(pts).tolist() == [True, True, False, False, False, False]


def test_dict_round_trip_and_manifest_shape():
    for cam in CAMERAS.values():
        d = cam.to_dict()
        assert set(d) == {"width", "height", "fx", "fy", "cx", "cy", "skew", "skew_yx", "model", "distortion"}
        d2 = json.loads(json.dumps(d))
        assert CameraModel.from_dict(d2) == cam
        assert hash(CameraModel.from_dict(d2)) == hash(cam)
    assert list(CAMERAS["brown"].to_dict()["distortion"]) == ["k1", "k2", "k3", "p1", "p2"]
    assert list(CAMERAS["owen"].to_dict()["distortion"]) == ["e1", "e2", "e3", "e4", "e5", "e6"]
    # the design's manifest example: no skew_yx, brown keys
    cam = CameraModel.from_dict({"width": 64, "height": 48, "fx": 50, "fy": 50, "cx": 31.5, "cy": 23.5,
                                 "skew": 0.0, "model": "brown", "distortion": {"k1": 0.01}})
    assert cam.skew_yx == 0.0 and dict(cam.distortion) == {"k1": 0.01, "k2": 0.0, "k3": 0.0, "p1": 0.0, "p2": 0.0}
    # a pinhole manifest that spells out zero Brown coefficients
    cam = CameraModel.from_dict({"width": 64, "height": 48, "fx": 50, "fy": 50, "cx": 31.5, "cy": 23.5,
                                 "model": "pinhole", "distortion": {"k1": 0.0, "p2": 0.0}})
    assert dict(cam.distortion) == {}


def test_frozen_and_immutable_distortion():
    cam = CAMERAS["brown"]
    with pytest.raises(dataclasses.FrozenInstanceError):
        cam.fx = 1.0
    with pytest.raises(TypeError):
        cam.distortion["k1"] = 0.0
    assert dataclasses.replace(cam, fx=901.0).fx == 901.0


# --------------------------------------------------------------------------- validation
GOOD = dict(width=64, height=48, fx=50.0, fy=50.0, cx=31.5, cy=23.5)


@pytest.mark.parametrize("change,field", [
    ({"fx": -5.0}, "camera.fx"),
    ({"fy": 0.0}, "camera.fy"),
    ({"fx": float("nan")}, "camera.fx"),
    ({"fy": float("inf")}, "camera.fy"),
    ({"width": 0}, "camera.width"),
    ({"height": -3}, "camera.height"),
    ({"width": 64.5}, "camera.width"),
    ({"width": True}, "camera.width"),
    ({"cx": float("nan")}, "camera.cx"),
    ({"cy": "23"}, "camera.cy"),
    ({"skew": float("inf")}, "camera.skew"),
    ({"skew_yx": None}, "camera.skew_yx"),
    ({"model": "fisheye"}, "camera.model"),
    ({"model": "brown", "distortion": {"k4": 0.1}}, "camera.distortion.k4"),
    ({"model": "owen", "distortion": {"k1": 0.1}}, "camera.distortion.k1"),
    ({"model": "brown", "distortion": {"k1": float("nan")}}, "camera.distortion.k1"),
    ({"model": "brown", "distortion": {"k1": "0.1"}}, "camera.distortion.k1"),
    ({"model": "brown", "distortion": [0.1, 0.0]}, "camera.distortion"),
    ({"distortion": {"k1": 0.1}}, "camera.distortion.k1"),
    ({"skew": 50.0, "skew_yx": 50.0}, "singular"),
])
def test_bad_inputs_raise_user_error(change, field):
    with pytest.raises(UserError) as info:
        CameraModel(**{**GOOD, **change})
    msg = str(info.value)
    assert field in msg and "\n" not in msg


def test_fx_message_is_exact():
    with pytest.raises(UserError, match=r"^camera\.fx must be a positive finite number, got -5\.0$"):
        CameraModel(**{**GOOD, "fx": -5.0})


def test_from_dict_errors():
    with pytest.raises(UserError, match="camera.focal"):
        CameraModel.from_dict({**GOOD, "focal": 3.0})
    with pytest.raises(UserError, match="camera.cy is missing"):
        CameraModel.from_dict({k: v for k, v in GOOD.items() if k != "cy"})
    with pytest.raises(UserError, match="camera"):
        CameraModel.from_dict([1, 2, 3])
    with pytest.raises(UserError, match="camera.Kx"):
        CameraModel.from_retina(10.0, float("nan"), 0.0, 0.0, 1.0, 5.0, 5.0, 10, 10)
    with pytest.raises(UserError, match="focal_length_mm"):
        CameraModel.from_retina(-1.0, 1.0, 0.0, 0.0, 1.0, 5.0, 5.0, 10, 10)
