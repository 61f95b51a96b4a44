"""Retina and SPC on real Mitsuba renders of a small terrain (hills, craters, boulders, albedo texture).

The terrain is an in-memory ``trimesh`` body lit with the McEwen law; the estimators get coarser maplets
derived from the DEM with height errors. Oracle: the projection of each landmark centre with the true
pose (the truth pixel, docs/architecture.md).
"""

from __future__ import annotations

import numpy as np
import pytest
from terrain_fixtures import (
    CAMERA,
    SUN,
    make_maplets,
    render_dn,
    terrain_dem,
    true_pose,
)


@pytest.fixture(scope="module")
def scene():
    dem = terrain_dem()
    pose = true_pose()
    out, dn = render_dn(dem, pose)
    return dem, make_maplets(dem), pose, out, dn


def _truth(pose, maplets):
    from estimators.retina import project_point

    return np.array([project_point(CAMERA, pose, m.center_m) for m in maplets])


def _errors(results, truth):
    return np.array([[r.meas_s - t[0], r.meas_l - t[1]] for r, t in zip(results, truth)])


def test_retina_true_pose_matches_truth_projection(scene):
    """Acceptance: well-lit, unoccluded landmarks measured to < 0.3 px of the truth projection."""
    from estimators.retina import RetinaOptions, build_mesh, measure_frame

    dem, maplets, pose, out, dn = scene
    res = measure_frame(dn.astype(float), [build_mesh(m) for m in maplets], CAMERA, pose, SUN, [4] * 3,
                        RetinaOptions())
    assert all(r.has_result for r in res), [r.flags for r in res]
    err = _errors(res, _truth(pose, maplets))
    print("retina true-pose errors (px):", np.round(err, 3).tolist())
    assert np.hypot(*err.T).max() < 0.3
    assert min(r.score for r in res) > 0.8


def _offset_pose(pose):
    from scipy.spatial.transform import Rotation

    from estimators.retina import CameraPoseEstimate

    R = pose.R_body_from_cam @ Rotation.from_rotvec([3e-3, 2e-3, 2e-3]).as_matrix()
    return CameraPoseEstimate(R, pose.position_m + np.array([0.35, 0.3, 0.2]))


def test_retina_recovers_apriori_pose_offset(scene):
    """A-priori pose off by 0.5 m and 4 mrad: predictions move by several px, the search distance comes
    from the covariance, and the measured shifts bring every landmark back to < 0.3 px of truth."""
    from estimators.retina import RetinaOptions, build_mesh, measure_frame, search_radius_px

    dem, maplets, pose, out, dn = scene
    ap = _offset_pose(pose)
    cov_p, cov_r = np.diag([0.3, 0.3, 0.3]) ** 2, np.diag([4e-3] * 3) ** 2
    radii = [search_radius_px(CAMERA, ap, m.center_m, cov_p, cov_r) for m in maplets]
    res = measure_frame(dn.astype(float), [build_mesh(m) for m in maplets], CAMERA, ap, SUN, radii, RetinaOptions())
    truth = _truth(pose, maplets)
    pred_off = np.array([[r.pred_s, r.pred_l] for r in res]) - truth
    assert np.hypot(*pred_off.T).min() > 2.0, "the offset must move the predictions by pixels"
    assert all(r.has_result and not r.flags for r in res), [r.flags for r in res]
    err = _errors(res, truth)
    print("a-priori offset (px):", np.round(pred_off, 2).tolist(), "retina errors:", np.round(err, 3).tolist())
    assert np.hypot(*err.T).max() < 0.3
    np.testing.assert_allclose([[r.ds, r.dl] for r in res], -pred_off, atol=0.3)


def test_retina_template_matches_mitsuba_render_of_the_maplet():
    """Oracle for the synthetic image: Mitsuba renders the maplet's own facets (McEwen law, maplet albedo
    per vertex, direct sun with shadows); Retina's supersampled template must agree up to a constant."""
    from estimators.retina import TemplateOptions, build_mesh, render_template

    dem = terrain_dem()
    M = make_maplets(dem)[1]
    mesh = build_mesh(M)
    V, Fc = mesh.vertices_faces()
    from renderlab.photometry import make_law
    from renderlab.render.scene import BodySpec

    body = BodySpec(name="maplet", body_id=0, shape="trimesh", center_m=np.asarray(M.center_m), R_render_from_body=np.eye(3),
                    law=make_law("mcewen"), albedo=1.0, vertices=V, faces=Fc, vertex_albedo=np.asarray(M.albedo).ravel())
    from scipy.spatial.transform import Rotation

    from renderlab.dynamics.camera_paths import CameraPose
    from renderlab.render.mitsuba_backend import MitsubaBackend
    from renderlab.render.scene import FrameSpec, RenderSettings, SceneDescription, SunSpec

    pose = true_pose()
    sun = np.array([0.8, 0.3, 0.3]) / np.linalg.norm([0.8, 0.3, 0.3])  # low sun (17 deg): long cast shadows
    be = MitsubaBackend(SceneDescription(bodies=[body]), RenderSettings(spp=64))
    out = be.render(FrameSpec(0, CameraPose(0.0, pose.position_m, Rotation.from_matrix(pose.R_body_from_cam)),
                              CAMERA, SunSpec(sun, np.pi)), seed=2)
    tpl = render_template(mesh, CAMERA, pose, sun, TemplateOptions(supersample=6))
    h, w = tpl.image.shape
    L = np.full((h, w), np.nan)
    ys, xs = np.mgrid[0:h, 0:w]
    ins = (ys + tpl.l0 >= 0) & (ys + tpl.l0 < CAMERA.height) & (xs + tpl.s0 >= 0) & (xs + tpl.s0 < CAMERA.width)
    L[ins] = out.radiance[ys[ins] + tpl.l0, xs[ins] + tpl.s0]
    from scipy.ndimage import binary_erosion

    inner = binary_erosion(tpl.valid, iterations=1) & ins
    a, b = tpl.image[inner], L[inner]
    assert (a == 0).mean() > 0.01, "the maplet must have cast shadows"
    rel = np.abs(a - b) / np.maximum(b.mean(), 1e-12)
    corr = np.corrcoef(a, b)[0, 1]
    print(f"template vs Mitsuba: corr {corr:.4f}, median |diff|/mean {np.median(rel):.4f}, p95 {np.percentile(rel, 95):.4f}")
    assert corr > 0.99
    assert np.median(rel) < 0.02


def test_spc_on_the_same_frames(scene):
    """SPC-style method on the same render, true and offset a-priori pose: it runs, its results (when it
    gives one) are within 0.5 px, and its error is printed next to Retina's. The paper found SPC biased;
    on this terrain and sun we assert only what the run supports (see the final report for the numbers)."""
    import estimators.spc as spc
    from estimators.retina import RetinaOptions, build_mesh, measure_frame, search_radius_px

    dem, maplets, pose, out, dn = scene
    truth = _truth(pose, maplets)
    for name, ap in (("true", pose), ("offset", _offset_pose(pose))):
        cov_p, cov_r = np.diag([0.3, 0.3, 0.3]) ** 2, np.diag([4e-3] * 3) ** 2
        radii = [search_radius_px(CAMERA, ap, m.center_m, cov_p, cov_r) for m in maplets]
        rs = spc.measure_frame(dn.astype(float), maplets, CAMERA, ap, SUN, radii)
        rr = measure_frame(dn.astype(float), [build_mesh(m) for m in maplets], CAMERA, ap, SUN, radii, RetinaOptions())
        es, er = _errors(rs, truth), _errors(rr, truth)
        print(f"{name} pose: SPC err {np.round(es, 3).tolist()} flags {[r.flags for r in rs]}; "
              f"Retina err {np.round(er, 3).tolist()}")
        got = np.array([r.has_result for r in rs])
        assert got.any(), [r.flags for r in rs]
        assert np.all(np.hypot(*es[got].T) < 0.5)
