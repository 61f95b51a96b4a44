"""Mitsuba backend: pixel convention and exact camera models, checked on rendered scenes."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from conftest import render_one, scenario_dict
from oracles import camera_rays, hit_plane_z0, hit_sphere

from renderlab.geometry.camera import CameraModel


def _reproject(out, spec, rng, n=300):
    hit = np.argwhere(out.body_id >= 0)
    pick = hit[rng.choice(len(hit), size=min(n, len(hit)), replace=False)]
    P = out.position[pick[:, 0], pick[:, 1]].astype(np.float64)
    cam = CameraModel.from_dict(spec.camera.to_dict())  # through the manifest's camera dict
    R = spec.pose.rotation.as_matrix()
    p_cam = (P - spec.pose.position_m) @ R
    sl = cam.project(p_cam)
    return sl, pick[:, ::-1].astype(float), p_cam, cam


@pytest.mark.parametrize(
    "camera",
    [
        {"fx": 70.0, "fy": 64.0, "cx": 33.7, "cy": 21.2},
        {"fx": 66.0, "fy": 71.0, "cx": 29.1, "cy": 26.4, "skew": 1.5, "skew_yx": -0.8},
        {"fx": 68.0, "fy": 63.0, "cx": 34.2, "cy": 22.9, "model": "brown",
         "distortion": {"k1": -0.21, "k2": 0.07, "k3": -0.01, "p1": 1.5e-3, "p2": -8e-4}},
        {"fx": 69.0, "fy": 65.0, "cx": 30.6, "cy": 24.1, "model": "owen",
         "distortion": {"e1": 2e-4, "e2": -0.15, "e3": 1e-3, "e4": 0.02, "e5": 1e-3, "e6": -2e-3}},
    ],
    ids=["pinhole", "skewed-K", "brown", "owen"],
)
def test_position_aov_reprojects_to_pixel_centre(camera):
    """Random hit pixels: project the position AOV through the manifest camera → that pixel's centre."""
    out, spec = render_one(scenario_dict(camera=camera))
    sl, centres, p_cam, cam = _reproject(out, spec, np.random.default_rng(5))
    err = np.hypot(*(sl - centres).T)
    assert err.max() <= 0.01, f"max reprojection error {err.max():.4f} px"
    if cam.model == "brown":  # independent projection with OpenCV
        d = cam.distortion
        K = np.array([[cam.fx, cam.skew, cam.cx], [0, cam.fy, cam.cy], [0, 0, 1.0]])
        sl_cv, _ = cv2.projectPoints(p_cam, np.zeros(3), np.zeros(3), K,
                                     np.array([d["k1"], d["k2"], d["p1"], d["p2"], d["k3"]]))
        assert np.abs(sl_cv[:, 0, :] - centres).max() <= 0.01


def test_pixel_centre_convention_against_analytic_rays():
    """Which body each pixel centre sees, and the range, agree with numpy ray casting through K."""
    out, spec = render_one(scenario_dict(render={"pixel_filter": "center", "spp": 1}))
    H, W = out.body_id.shape
    ll, ss = np.mgrid[0:H, 0:W]
    sl = np.column_stack([ss.ravel(), ll.ravel()]).astype(float)
    o, d = camera_rays(spec, sl)
    t_sph = hit_sphere(o, d, np.array([-0.5, 0.4, 1.0]), 1.0)
    t_pl = hit_plane_z0(o, d, (10, 10))
    t = np.minimum(t_sph, t_pl)
    expect_id = np.where(np.isinf(t), -1, np.where(t_sph < t_pl, 1, 0)).reshape(H, W)
    # Away from silhouettes (where the centre ray grazes an edge) the ids must agree exactly.
    grazing = np.abs(np.minimum(t_sph, 1e9) - np.minimum(t_pl, 1e9)).reshape(H, W) < 1e-6
    assert np.array_equal(out.body_id[~grazing], expect_id[~grazing])
    hit = np.isfinite(t)
    rel = np.abs(out.range_m.ravel()[hit] / t[hit] - 1)
    assert rel.max() < 1e-5, f"range AOV differs from analytic by {rel.max():.2e}"
    # A pixel-corner convention would shift everything by half a pixel: the sphere's outline moves.
    shifted = hit_sphere(*camera_rays(spec, sl + 0.5), np.array([-0.5, 0.4, 1.0]), 1.0)
    assert (np.isfinite(shifted) != np.isfinite(t_sph)).sum() > 0
