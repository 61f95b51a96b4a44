"""Retina's numerical kernels against independent oracles.

- onboard McEwen vs ``renderlab.photometry.mcewen`` (the lab's reference law);
- numba grid-DDA ray casting vs brute-force numpy Möller–Trumbore over every facet;
- eq. 9 vs OpenCV ``matchTemplate(TM_CCOEFF_NORMED)`` on fully valid windows, and vs ``numpy.corrcoef``
  on masked windows;
- the search distance's pixel covariance vs finite differences of the projection.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from estimators.landmarks.correlation import correlation_surface, correlation_surface_direct, correlation_surface_numpy
from estimators.onboard_photometry import mcewen_relative
from estimators.retina import CameraPoseEstimate, build_mesh, pixel_covariance, project_point
from estimators.retina.raytrace import trace_rays
from estimators.retina.raytrace_numpy import trace_bruteforce
from renderlab.geometry.camera import CameraModel
from renderlab.geometry.maplet import Maplet
from renderlab.geometry.rotations import look_at


@pytest.mark.parametrize("alpha0_deg, c", [(60.0, 2.0), (30.0, 1.0), (90.0, 0.5)])
def test_onboard_mcewen_matches_lab_law(alpha0_deg, c):
    from renderlab.photometry import mcewen

    rng = np.random.default_rng(1)
    mu0, mu, g, a = rng.uniform(-0.2, 1, 500), rng.uniform(-0.2, 1, 500), rng.uniform(0, 2.5, 500), rng.uniform(0, 2, 500)
    ref = mcewen(mu0, mu, g, a, alpha0=math.radians(alpha0_deg), ls_weight=c) * np.pi
    got = mcewen_relative(mu0, mu, g, a, math.radians(alpha0_deg), c)
    np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-15)
    assert np.all(got[(mu0 <= 0) | (mu <= 0)] == 0)


def _rough_maplet(n=25, seed=0):
    rng = np.random.default_rng(seed)
    h = rng.normal(0, 0.08, (n, n))
    h[10:13, 10:13] += 1.5  # a pillar that casts long shadows
    return Maplet(1, np.zeros(3), np.eye(3), 0.2, h, np.ones((n, n)))


def test_grid_raytracer_matches_bruteforce():
    mesh = build_mesh(_rough_maplet())
    rng = np.random.default_rng(2)
    N = 1500
    o = np.column_stack([rng.uniform(-3, 3, N), rng.uniform(-3, 3, N), rng.uniform(1, 15, N)])
    d = np.column_stack([rng.normal(0, 0.25, N), rng.normal(0, 0.25, N), -np.ones(N)])
    hit, P, Nn, _ = trace_rays(o, d, mesh.heights, mesh.cell_min, mesh.cell_max, mesh.spacing, mesh.normals,
                               np.zeros(3), 0.0)
    hb, tb, fb = trace_bruteforce(mesh, o, d)
    assert hb.sum() > N // 3 and (~hb).sum() > 20, "the rays must both hit and miss"
    np.testing.assert_array_equal(hit, hb)
    t = np.linalg.norm(P[hit] - o[hit], axis=1) / np.linalg.norm(d[hit], axis=1)
    np.testing.assert_allclose(t, tb[hb], rtol=0, atol=1e-9)
    V, Fc = mesh.vertices_faces()
    A, B, C = (V[Fc[fb[hb]]][:, k] for k in range(3))
    nb = np.cross(B - A, C - A)
    nb /= np.linalg.norm(nb, axis=1, keepdims=True)
    np.testing.assert_allclose(Nn[hit], nb, atol=1e-12)
    assert np.all(nb[:, 2] > 0), "facet normals point up (+z of the maplet)"


def test_shadow_rays_match_bruteforce():
    mesh = build_mesh(_rough_maplet())
    sun = np.array([0.8, 0.3, 0.6]) / np.linalg.norm([0.8, 0.3, 0.6])
    g = np.linspace(-2.3, 2.3, 60)
    X, Y = np.meshgrid(g, g)
    o = np.column_stack([X.ravel(), Y.ravel(), np.full(X.size, 10.0)])
    d = np.tile([0.0, 0.0, -1.0], (X.size, 1))
    eps = 1e-6
    hit, P, Nn, shadow = trace_rays(o, d, mesh.heights, mesh.cell_min, mesh.cell_max, mesh.spacing, mesh.normals,
                                    sun, eps)
    hs, _, _ = trace_bruteforce(mesh, P[hit] + eps * Nn[hit], np.tile(sun, (hit.sum(), 1)))
    assert 0.02 < hs.mean() < 0.98, "the scene must have shadows and lit ground"
    np.testing.assert_array_equal(shadow[hit], hs)


def test_correlation_equals_opencv_on_valid_windows():
    rng = np.random.default_rng(3)
    img = cv2.GaussianBlur(rng.normal(size=(90, 100)), (0, 0), 1.0)
    img = (img / img.std()).astype(np.float32).astype(np.float64)  # values exact in OpenCV's float32
    tpl = (img[30:62, 35:75] * 1.7 + 0.2 + 0.3 * rng.normal(size=(32, 40))).astype(np.float32).astype(np.float64)
    r = 12
    C, cnt = correlation_surface(img, tpl, None, 35, 30, r)
    Cd, _ = correlation_surface_direct(img, tpl, None, 35, 30, r)
    np.testing.assert_allclose(C, Cd, atol=1e-10)
    ref = cv2.matchTemplate(img[30 - r:62 + r, 35 - r:75 + r].astype(np.float32), tpl.astype(np.float32),
                            cv2.TM_CCOEFF_NORMED)
    assert C.shape == ref.shape == (2 * r + 1, 2 * r + 1)
    assert np.all(cnt == tpl.size)
    np.testing.assert_allclose(C, ref, atol=1e-6)
    assert np.unravel_index(np.argmax(C), C.shape) == (r, r)


def test_masked_correlation_matches_corrcoef_and_numpy_version():
    rng = np.random.default_rng(4)
    img = rng.random((50, 60))
    tpl = rng.random((20, 24))
    valid = rng.random(tpl.shape) > 0.3
    img_ok = rng.random(img.shape) > 0.1
    s0, l0, r = 40, 2, 6  # the window runs off the right and top edges at some shifts
    C, cnt = correlation_surface(img, tpl, valid, s0, l0, r, img_ok, min_count=10)
    for other in (correlation_surface_numpy, correlation_surface_direct):
        C2, cnt2 = other(img, tpl, valid, s0, l0, r, img_ok, min_count=10)
        np.testing.assert_array_equal(cnt, cnt2)
        np.testing.assert_allclose(C, C2, atol=1e-10, equal_nan=True)
    checked = 0
    for a in range(2 * r + 1):
        for b in range(2 * r + 1):
            ys, xs = np.nonzero(valid)
            li, si = ys + l0 + a - r, xs + s0 + b - r
            inside = (li >= 0) & (li < img.shape[0]) & (si >= 0) & (si < img.shape[1])
            li, si, ys, xs = li[inside], si[inside], ys[inside], xs[inside]
            keep = img_ok[li, si]
            assert cnt[a, b] == keep.sum()
            if keep.sum() >= 10:
                ref = np.corrcoef(tpl[ys[keep], xs[keep]], img[li[keep], si[keep]])[0, 1]
                assert abs(C[a, b] - ref) < 1e-10
                checked += 1
    assert checked > 50


def test_fully_usable_window_with_masked_template_matches_direct_and_corrcoef():
    """The fast path (every image pixel of the search window usable, template masked by its maplet
    coverage: numba FFT inputs, pruned inverse FFT) against the direct loop and numpy.corrcoef."""
    rng = np.random.default_rng(5)
    img = rng.random((70, 80))
    tpl = rng.random((25, 31))
    yy, xx = np.mgrid[:25, :31]
    valid = (np.abs(xx - 15) + np.abs(yy - 12)) <= 16  # a diamond, as a rotated maplet covers its box
    s0, l0, r = 30, 20, 9  # the window [21, 70) x [11, 54) lies inside the image
    C, cnt = correlation_surface(img, tpl, valid, s0, l0, r, None, min_count=10)
    Cd, cntd = correlation_surface_direct(img, tpl, valid, s0, l0, r, None, min_count=10)
    np.testing.assert_array_equal(cnt, cntd)
    assert np.all(cnt == valid.sum()) and np.all(np.isfinite(C))
    np.testing.assert_allclose(C, Cd, atol=1e-12)
    ys, xs = np.nonzero(valid)
    for a, b in [(0, 0), (r, r), (2 * r, 3), (5, 2 * r)]:
        ref = np.corrcoef(tpl[ys, xs], img[ys + l0 + a - r, xs + s0 + b - r])[0, 1]
        assert abs(C[a, b] - ref) < 1e-12


def test_pixel_covariance_matches_finite_differences():
    from scipy.spatial.transform import Rotation

    cam = CameraModel.from_dict({"width": 200, "height": 150, "fx": 220.0, "fy": 230.0, "cx": 97.0, "cy": 77.0,
                                 "model": "brown", "distortion": {"k1": -0.1, "p1": 0.001}})
    pos = np.array([3.0, -20.0, 12.0])
    R = look_at(pos, np.zeros(3), np.array([0, 0, 1.0])).as_matrix()
    pose = CameraPoseEstimate(R, pos)
    p = np.array([1.0, 2.0, 0.5])
    base = project_point(cam, pose, p)
    J = np.zeros((2, 6))
    h = 1e-6
    for k in range(3):
        e = np.eye(3)[k] * h
        J[:, k] = (project_point(cam, CameraPoseEstimate(R, pos + e), p) - base) / h
        J[:, 3 + k] = (project_point(cam, CameraPoseEstimate(R @ Rotation.from_rotvec(e).as_matrix(), pos), p) - base) / h
    Sp, Sr = np.diag([0.3, 0.1, 0.2]) ** 2, np.diag([1e-3, 2e-3, 5e-4]) ** 2
    ref = J[:, :3] @ Sp @ J[:, :3].T + J[:, 3:] @ Sr @ J[:, 3:].T
    np.testing.assert_allclose(pixel_covariance(cam, pose, p, Sp, Sr), ref, rtol=1e-4)


@pytest.mark.parametrize("lens", [{"model": "brown", "distortion": {"k1": -0.05}},
                                  {"model": "pinhole", "skew": 0.4, "skew_yx": -0.3}])
def test_fused_template_kernel_matches_numpy_pipeline(lens):
    """The fused numba synthetic image (trace + shadow + McEwen + supersampling) equals the plain-numpy
    pipeline (brute-force tracer, vectorised ``mcewen_relative``, rays from ``CameraModel.unproject``).
    Pinhole: the kernel makes its own rays (and the template box its own projection)."""
    from estimators.retina import TemplateOptions, render_template

    M = _rough_maplet(n=17)
    mesh = build_mesh(M)
    cam = CameraModel.from_dict({"width": 60, "height": 50, "fx": 40.0, "fy": 42.0, "cx": 29.0, "cy": 24.0, **lens})
    pos = np.array([0.7, -0.4, 6.0])
    pose = CameraPoseEstimate(look_at(pos, np.zeros(3), np.array([0.0, 1.0, 0.0])).as_matrix(), pos)
    sun = np.array([0.7, 0.2, 0.5]) / np.linalg.norm([0.7, 0.2, 0.5])
    a = render_template(mesh, cam, pose, sun, TemplateOptions(supersample=2, tracer="numba"))
    b = render_template(mesh, cam, pose, sun, TemplateOptions(supersample=2, tracer="numpy"))
    sl = cam.project(pose.to_camera(M.points_body().reshape(-1, 3)))  # the box from the camera model itself
    lo, hi = np.floor(sl.min(axis=0)).astype(int), np.ceil(sl.max(axis=0)).astype(int)
    assert (a.s0, a.l0, a.s0 + a.image.shape[1] - 1, a.l0 + a.image.shape[0] - 1) == (lo[0], lo[1], hi[0], hi[1])
    assert a.valid.sum() > 100 and (a.image[a.valid] == 0).any() and a.shadow_fraction > 0
    np.testing.assert_array_equal(a.valid, b.valid)
    np.testing.assert_allclose(a.image, b.image, rtol=1e-9, atol=1e-12)
    assert a.shadow_fraction == pytest.approx(b.shadow_fraction)
