"""In-memory triangle meshes (``shape = "trimesh"``) with per-vertex albedo, rendered by Mitsuba.

Oracle: a tilted square of two triangles whose vertex albedo is a linear function of position.
Barycentric interpolation reproduces a linear function exactly, so every hit pixel's radiance must
equal A(P)·E·cos(i)/π with P from the position AOV and cos(i) from the known facet normal.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from renderlab.dynamics.camera_paths import CameraPose
from renderlab.geometry.camera import CameraModel
from renderlab.geometry.rotations import look_at
from renderlab.photometry import make_law
from renderlab.render.mitsuba_backend import MitsubaBackend
from renderlab.render.scene import BodySpec, FrameSpec, RenderSettings, SceneDescription, SunSpec

A0, AX, AY = 0.5, 0.1, -0.15  # albedo(x, y) in the body frame


def _albedo(p_body):
    return A0 + AX * p_body[..., 0] + AY * p_body[..., 1]


@pytest.mark.parametrize("variant", ["llvm_ad_mono", "scalar_rgb"])
def test_trimesh_vertex_albedo_matches_linear_oracle(variant):
    V = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
    F = np.array([[0, 1, 2], [0, 2, 3]])
    R = Rotation.from_euler("xyz", [20, -10, 35], degrees=True).as_matrix()
    c = np.array([0.3, -0.2, 0.1])
    body = BodySpec(name="tile", body_id=0, shape="trimesh", center_m=c, R_render_from_body=R,
                    law=make_law("lambert"), albedo=1.0, vertices=V, faces=F, vertex_albedo=_albedo(V))
    size = 24 if variant.startswith("scalar") else 48
    cam = CameraModel.from_dict({"width": size, "height": size, "fx": size * 1.1, "fy": size * 1.1,
                                 "cx": (size - 1) / 2, "cy": (size - 1) / 2})
    pos = c + R @ np.array([0.2, 0.1, 3.0])
    pose = CameraPose(0.0, pos, look_at(pos, c, np.array([0.0, 1.0, 0.0])))
    sun_dir = R @ np.array([0.3, -0.2, 1.0])
    sun_dir /= np.linalg.norm(sun_dir)
    be = MitsubaBackend(SceneDescription(bodies=[body]), RenderSettings(variant=variant, spp=1, pixel_filter="center"))
    out = be.render(FrameSpec(0, pose, cam, SunSpec(sun_dir, 1000.0)), seed=0)

    hit = out.body_id == 0
    assert hit.sum() > 0.3 * size * size, "the tile should fill much of the image"
    assert np.all(out.body_id[~hit] == -1)
    P = out.position[hit].astype(np.float64)
    p_body = (P - c) @ R  # R^T (P - c)
    assert np.abs(p_body[:, 2]).max() < 1e-5, "hits lie on the tile's plane"
    n_render = R[:, 2]
    cos_i = float(sun_dir @ n_render)
    expected = _albedo(p_body) * 1000.0 * cos_i / np.pi
    got = out.radiance[hit] if out.radiance.ndim == 2 else out.radiance[hit].mean(-1)
    # keep away from the triangle edges' float32 ambiguity: the linear field is the same on both sides anyway
    rel = np.abs(got - expected) / expected
    assert np.median(rel) < 1e-5 and rel.max() < 1e-3, (np.median(rel), rel.max())


def test_trimesh_uv_albedo_map_orientation():
    """A 2×2 albedo map on a uv-mapped square: each quadrant's radiance names the map cell it shows.

    Oracle: the BodySpec docstring's convention (u → column, v → row top to bottom); with bilinear
    filtering, points at each quadrant's centre (a texel centre) see that cell's value.
    """
    V = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
    F = np.array([[0, 1, 2], [0, 2, 3]])
    uv = (V[:, :2] + 1) / 2  # u = (x+1)/2, v = (y+1)/2
    amap = np.array([[0.2, 0.4], [0.6, 0.8]])  # row 0 ↔ v < ½ ↔ y < 0
    body = BodySpec(name="tile", body_id=0, shape="trimesh", center_m=np.zeros(3), R_render_from_body=np.eye(3),
                    law=make_law("lambert"), albedo=1.0, vertices=V, faces=F, vertex_uv=uv, albedo_map=amap)
    cam = CameraModel.from_dict({"width": 40, "height": 40, "fx": 40, "fy": 40, "cx": 19.5, "cy": 19.5})
    pos = np.array([0.0, 0.0, 2.0])
    pose = CameraPose(0.0, pos, look_at(pos, np.zeros(3), np.array([0.0, 1.0, 0.0])))
    be = MitsubaBackend(SceneDescription(bodies=[body]), RenderSettings(spp=1, pixel_filter="center"))
    out = be.render(FrameSpec(0, pose, cam, SunSpec(np.array([0.0, 0.0, 1.0]), np.pi)), seed=0)
    P = out.position.astype(float)
    for (x, y), expected in {(-0.5, -0.5): 0.2, (0.5, -0.5): 0.4, (-0.5, 0.5): 0.6, (0.5, 0.5): 0.8}.items():
        near = (np.abs(P[..., 0] - x) < 0.03) & (np.abs(P[..., 1] - y) < 0.03)
        assert near.sum() >= 1
        np.testing.assert_allclose(out.radiance[near], expected, atol=0.02)
    # everywhere: bilinear interpolation of the map at (u·W − ½, v·H − ½), clamped at the border
    hit = out.body_id == 0
    u, v = (P[hit, 0] + 1) / 2, (P[hit, 1] + 1) / 2
    fx, fy = np.clip(u * 2 - 0.5, 0, 1), np.clip(v * 2 - 0.5, 0, 1)
    bil = ((1 - fx) * (1 - fy) * amap[0, 0] + fx * (1 - fy) * amap[0, 1]
           + (1 - fx) * fy * amap[1, 0] + fx * fy * amap[1, 1])
    np.testing.assert_allclose(out.radiance[hit], bil, rtol=2e-3)
