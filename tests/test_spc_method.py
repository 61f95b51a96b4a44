"""SPC-style method pieces against independent oracles: the image resampled into the maplet frame vs
OpenCV's ``projectPoints``; the horizon-march shadow vs the analytic shadow of a wall; a known shift of a
Retina-rendered maplet recovered in the maplet frame and converted back to image Δs, Δl."""

from __future__ import annotations

import math

import cv2
import numpy as np

import estimators.spc as spc
from estimators.retina import CameraPoseEstimate, build_mesh, project_point, render_template
from estimators.spc.method import approximate_shadow
from renderlab.geometry.camera import CameraModel
from renderlab.geometry.maplet import Maplet
from renderlab.geometry.rotations import look_at

CAM = CameraModel.from_dict({"width": 120, "height": 100, "fx": 100.0, "fy": 104.0, "cx": 58.3, "cy": 51.1})


def _maplet(n=31, s=0.1, seed=0):
    from scipy.ndimage import gaussian_filter

    rng = np.random.default_rng(seed)
    h = gaussian_filter(rng.normal(0, 0.5, (n, n)), 1.5)
    a = np.clip(1 + 0.3 * gaussian_filter(rng.normal(size=(n, n)), 1.0) / 0.28, 0.3, 3)
    R = look_at(np.zeros(3), np.array([0.1, -0.05, 1.0]), np.array([0.0, 1.0, 0.0])).as_matrix()
    R = R @ np.diag([1.0, -1.0, -1.0])  # proper rotation whose z axis tilts away from body +z a little
    return Maplet(2, np.array([0.3, -0.1, 0.2]), R, s, h, a)


def test_extract_in_maplet_matches_opencv_projection():
    M = _maplet()
    pos = np.array([0.8, -0.5, 5.0])
    R = look_at(pos, M.center_m, np.array([0.0, 1.0, 0.0])).as_matrix()
    pose = CameraPoseEstimate(R, pos)
    ls, ss = np.mgrid[0:CAM.height, 0:CAM.width].astype(float)
    image = 3.0 * ss + 5.0 * ls + 2.0  # bilinear sampling of a linear image is exact
    pad = 2
    E, ok = spc.extract_in_maplet(image, CAM, pose, M, pad, px_per_cell=1.0)
    h = np.pad(M.heights_m, pad, mode="edge")
    t = (np.arange(M.n + 2 * pad) - (M.n + 2 * pad - 1) / 2) * M.spacing_m
    X, Y = np.meshgrid(t, t)
    P = M.to_body(np.stack([X, Y, h], -1)).reshape(-1, 3)
    rvec, _ = cv2.Rodrigues(R.T)
    sl, _ = cv2.projectPoints(P, rvec, -R.T @ pos, CAM.K_matrix, np.zeros(5))
    sl = sl.reshape(E.shape + (2,))
    assert ok.mean() > 0.9
    np.testing.assert_allclose(E[ok], 3 * sl[ok][:, 0] + 5 * sl[ok][:, 1] + 2, rtol=2e-6)


def test_horizon_shadow_of_a_wall():
    n, s = 41, 0.1
    h = np.zeros((n, n))
    h[:, 25:] = 0.5  # a 0.5 m step up at column 25
    elev = math.radians(20)
    sun = np.array([math.cos(elev), 0.0, math.sin(elev)])  # sun toward +x: the wall shadows x < wall
    sh = approximate_shadow(h, s, sun)
    length = 0.5 / math.tan(elev) / s  # analytic shadow length, cells (13.7)
    row = sh[20]
    shadowed = np.flatnonzero(row[:25])
    assert not row[25:].any()
    assert shadowed.max() == 24 and abs(len(shadowed) - length) <= 1.0, (len(shadowed), length)


def test_spc_recovers_known_shift_of_rendered_maplet():
    M = _maplet(n=41)
    mesh = build_mesh(M)
    sun = M.R_body_from_maplet @ (np.array([0.5, 0.3, 0.8]) / np.linalg.norm([0.5, 0.3, 0.8]))
    pos = M.to_body(np.array([0.2, 0.1, 7.0]))
    R = look_at(pos, M.center_m, M.R_body_from_maplet[:, 1]).as_matrix()
    true = CameraPoseEstimate(R, pos)
    tpl = render_template(mesh, CAM, true, sun)
    img = np.zeros((CAM.height, CAM.width))
    valid = np.zeros_like(img, bool)
    sl = (slice(tpl.l0, tpl.l0 + tpl.image.shape[0]), slice(tpl.s0, tpl.s0 + tpl.image.shape[1]))
    img[sl], valid[sl] = tpl.image, tpl.valid
    truth = project_point(CAM, true, M.center_m)
    ap = CameraPoseEstimate(R, pos + R @ np.array([0.12, -0.09, 0.0]))
    r = spc.measure_landmark(img, M, CAM, ap, sun, 4, image_valid=valid)
    shift = np.hypot(r.pred_s - truth[0], r.pred_l - truth[1])
    err = np.hypot(r.meas_s - truth[0], r.meas_l - truth[1])
    assert r.has_result and shift > 1.0, (r.flags, shift)
    assert err < 0.3, (err, shift)


def test_spc_shading_follows_a_tabulated_L_against_the_lab_mcewen_law():
    """With ``L_table`` SPC shades with McEwen's weight L(α) from the table: a table of exp(−α/30°) gives the
    lab's McEwen law with α0 = 30° (renderlab.photometry, the oracle) up to one scale, and differs from the
    default exp(−α/60°)."""
    from renderlab.photometry import mcewen

    m = _maplet()
    sun = np.array([0.5, 0.2, 0.84])
    sun /= np.linalg.norm(sun)
    to_cam = np.array([-0.3, 0.1, 1.0]) * 40.0
    grid = np.linspace(0.0, math.pi, 181)
    opts = spc.SpcOptions(L_table=tuple(np.exp(-grid / math.radians(30.0))))
    img, usable = spc.predict_maplet(m, to_cam, sun, opts)
    img0, _ = spc.predict_maplet(m, to_cam, sun)
    gy, gx = np.gradient(np.asarray(m.heights_m), m.spacing_m)
    n = np.stack([-gx, -gy, np.ones_like(gx)], -1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    r = to_cam / np.linalg.norm(to_cam)
    mu0, mu, g = n @ sun, n @ r, math.acos(float(sun @ r))
    ref = mcewen(mu0, mu, g, m.albedo, alpha0=math.radians(30.0))
    ok = usable & (img > 0)
    assert ok.sum() > 100
    ratio = img[ok] / ref[ok]
    assert np.ptp(ratio) / ratio.mean() < 1e-4
    assert np.max(np.abs(img0[ok] / img[ok] - 1.0)) > 0.01
