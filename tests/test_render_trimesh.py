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
