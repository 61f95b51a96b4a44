"""In-memory triangle meshes (``shape = "trimesh"``) and mesh files, rendered by Mitsuba and Cycles.

* Per-vertex albedo (Mitsuba). Oracle: a tilted square of two triangles whose vertex albedo is a linear
  function of position. Barycentric interpolation reproduces a linear function exactly, so every hit pixel's
  radiance must equal A(P)·E·cos(i)/π with P from the position AOV and cos(i) from the known facet normal.
* uv + albedo map orientation (both renderers).
* Mesh files of every format (OBJ/PLY/STL/GLB, quads, units, smooth normals) through
  :mod:`renderlab.render.mesh_io`: ids and range of both renderers vs the float64 ray caster.
* ``renderlab render --save-blend``: the .blend reloads in a fresh bpy with the same camera and bodies.
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


@pytest.mark.parametrize("renderer", ["mitsuba", "cycles"])
def test_trimesh_uv_albedo_map_orientation(renderer):
    """A 2×2 albedo map on a uv-mapped square: each quadrant's radiance names the map cell it shows.

    Oracle: the BodySpec docstring's convention (u → column, v → row top to bottom); with bilinear
    filtering, points at each quadrant's centre (a texel centre) see that cell's value. (Cycles: the map
    used to render black — setting the image's colour space after its pixels regenerated it.)
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
    be = _backend(renderer, SceneDescription(bodies=[body]), RenderSettings(spp=1, pixel_filter="center"))
    try:
        out = be.render(FrameSpec(0, pose, cam, SunSpec(np.array([0.0, 0.0, 1.0]), np.pi)), seed=0)
    finally:
        getattr(be, "close", lambda: None)()
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


# ------------------------------------------------------------------------------------------- mesh files
# One analytic world whose bodies are mesh files of every format (read by renderlab.render.mesh_io, rendered
# from arrays by both backends), against the float64 ray caster of renderlab.render.ray_oracle.
MESH_FILES = {  # body name → (file, units, normals, centre)
    "quad_obj": ("quad.obj", None, None, [-1.7, 0.9, 0.0]),
    "quad_ply_ascii": ("quad_ascii.ply", None, None, [0.0, 0.9, 0.0]),  # failed before: Mitsuba's own PLY reader
    "quad_ply_binary_km": ("quad_km.ply", "km", None, [1.7, 0.9, 0.0]),
    "stl_cm": ("box_cm.stl", "cm", None, [-1.7, -0.9, 0.0]),
    "glb": ("box.glb", None, None, [0.0, -0.9, 0.0]),
    "ico_smooth": ("ico.obj", None, "smooth", [1.7, -0.9, 0.0]),
}


def _write_mesh_files(d):
    import trimesh
    from mesh_fixtures import write_quad_box, write_trimesh

    write_quad_box(d / "quad.obj")
    write_quad_box(d / "quad_ascii.ply")
    write_quad_box(d / "quad_km.ply", 1e-3, "binary_little_endian")
    write_trimesh(d / "box_cm.stl", trimesh.creation.box((100.0, 100.0, 100.0)))
    write_trimesh(d / "box.glb", trimesh.creation.box((1.0, 1.0, 1.0)))
    write_trimesh(d / "ico.obj", trimesh.creation.icosphere(subdivisions=2, radius=0.6))


@pytest.fixture(scope="module")
def mesh_scene(tmp_path_factory):
    """(SceneDescription, FrameSpec) of the mesh-file world, 96×64 px."""
    pytest.importorskip("trimesh")
    from renderlab.scenario import AnalyticWorld
    from renderlab.worlds.analytic import build_scene

    d = tmp_path_factory.mktemp("meshes")
    _write_mesh_files(d)
    bodies = []
    for k, (name, (file, units, normals, centre)) in enumerate(MESH_FILES.items()):
        b = {"name": name, "shape": "mesh", "file": file, "center_m": centre,
             "rotation_deg": [15 + 7 * k, 25, 35 - 9 * k], "albedo": 0.4}
        b.update({key: v for key, v in (("units", units), ("normals", normals)) if v})
        bodies.append(b)
    scene = build_scene(AnalyticWorld.model_validate({"kind": "analytic", "bodies": bodies}), d)
    cam = CameraModel.from_dict({"width": 96, "height": 64, "fx": 100.0, "fy": 100.0, "cx": 47.5, "cy": 31.5})
    pos = np.array([0.4, -6.5, 5.0])
    pose = CameraPose(0.0, pos, look_at(pos, np.zeros(3), np.array([0.0, 0.0, 1.0])))
    return scene, FrameSpec(0, pose, cam, SunSpec(np.array([0.4, -0.5, 0.75]) / np.linalg.norm([0.4, -0.5, 0.75]),
                                                   1000.0))


def _backend(renderer, scene, settings):
    if renderer == "cycles":
        pytest.importorskip("bpy")
        from renderlab.render.cycles_backend import CyclesBackend

        return CyclesBackend(scene, settings)
    return MitsubaBackend(scene, settings)


def _oracle_first_hits(oracle, o, d):
    from renderlab.render.ray_oracle import _first_hit

    t, prim, _, _ = _first_hit(oracle, np.ascontiguousarray(o, float), np.ascontiguousarray(d, float),
                               np.arange(len(oracle.tri)), 0.0)
    ids = np.where(np.isfinite(t), oracle.tri_body[np.maximum(prim, 0)], -1)
    return t, ids, prim


def test_mesh_files_become_arrays(mesh_scene):
    """Every format arrives as an in-memory trimesh body in metres: 12 triangles per box, 1 m edges."""
    scene, _ = mesh_scene
    for body in scene.bodies:
        assert body.shape == "trimesh" and body.mesh_path is None, body.name
        ext = body.vertices.max(0) - body.vertices.min(0)
        if body.name == "ico_smooth":
            assert len(body.faces) == 320 and body.vertex_normals is not None
        else:
            assert len(body.faces) == 12 and np.allclose(ext, 1.0) and body.vertex_normals is None, body.name


@pytest.mark.parametrize("renderer", ["mitsuba", "cycles"])
def test_mesh_files_render_like_the_ray_oracle(renderer, mesh_scene):
    """Body ids and range of Mitsuba and Cycles vs the float64 ray caster; flat facets vs smooth normals.

    ids: equal wherever the oracle's 3×3 neighbourhood is one body, ≤ 1 % of all pixels off (silhouettes).
    range: ‖P − camera‖ equals the oracle's first hit along the renderer's own ray through P (≤ 1e-5
    relative) and the centre ray's (Mitsuba ≤ 1e-5; Cycles' truth samples lie within ±0.005 px of the centre).
    normals: flat bodies show their facet normal, the smooth icosphere the interpolated one (closer to radial).
    """
    from scipy import ndimage

    from renderlab.render.ray_oracle import oracle_scene

    scene, spec = mesh_scene
    be = _backend(renderer, scene, RenderSettings(spp=2, pixel_filter="center"))
    try:
        out = be.render(spec, seed=3)
    finally:
        getattr(be, "close", lambda: None)()
    oracle = oracle_scene(scene)
    assert oracle is not None, "mesh bodies must reach the oracle as triangles"
    cam, R, c0 = spec.camera, spec.pose.rotation.as_matrix(), np.asarray(spec.pose.position_m, float)
    sl = cam.pixel_grid().reshape(-1, 2)
    d = cam.unproject(sl) @ R.T
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    t, ids, prim = _oracle_first_hits(oracle, np.broadcast_to(c0, d.shape), d)
    ids2 = ids.reshape(out.body_id.shape)
    inner = (ndimage.minimum_filter(ids2, 3, mode="nearest") == ndimage.maximum_filter(ids2, 3, mode="nearest"))
    got = out.body_id
    off = int((got != ids2).sum())
    for b in scene.bodies:
        assert (ids2[inner] == b.body_id).sum() >= 20, f"{b.name} should be visible"
    assert np.array_equal(got[inner], ids2[inner]), f"{renderer}: ids differ away from silhouettes"
    assert off <= 0.01 * got.size, f"{renderer}: {off} pixels with another id"

    hit = (got >= 0).ravel() & inner.ravel() & (ids >= 0)
    P = out.position.reshape(-1, 3)[hit].astype(np.float64)
    rng = out.range_m.ravel()[hit]
    u = (P - c0) / rng[:, None]
    t_own, _, _ = _oracle_first_hits(oracle, np.broadcast_to(c0, u.shape), u)
    rel_own = np.abs(rng / t_own - 1)
    rel_centre = np.abs(rng / t[hit] - 1)
    assert rel_own.max() <= 1e-5, f"{renderer}: range vs own-ray oracle {rel_own.max():.2e}"
    assert rel_centre.max() <= (1e-5 if renderer == "mitsuba" else 2e-4), rel_centre.max()

    N = out.normal.reshape(-1, 3)[hit].astype(np.float64)
    body = ids[hit]
    cos_face = np.einsum("ij,ij->i", N, oracle.tri_normal[prim[hit]])
    ico = [b.body_id for b in scene.bodies if b.name == "ico_smooth"][0]
    flat = body != ico
    assert cos_face[flat].min() > 1 - 1e-5, f"{renderer}: flat facets, min cos {cos_face[flat].min()}"
    centre = np.asarray(scene.bodies[ico].center_m, float)
    radial = (P[~flat] - centre) / np.linalg.norm(P[~flat] - centre, axis=1, keepdims=True)
    ang_radial = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", N[~flat], radial), -1, 1)))
    ang_face = np.degrees(np.arccos(np.clip(cos_face[~flat], -1, 1)))
    assert np.median(ang_radial) < 0.5 * np.median(ang_face), (np.median(ang_radial), np.median(ang_face))
    print(f"{renderer}: ids off {off}/{got.size} (interior: 0 of {int(inner.sum())}), range rel max "
          f"{rel_own.max():.2e} (own ray) {rel_centre.max():.2e} (centre ray), flat normals min cos "
          f"{cos_face[flat].min():.8f}, smooth: median {np.median(ang_radial):.2f}° from radial vs "
          f"{np.median(ang_face):.2f}° from the facet")


# ------------------------------------------------------------------------------------------- --save-blend
SAVE_BLEND_SCENE = """name = "save_blend"
[world]
kind = "analytic"
[[world.bodies]]
name = "ground"
shape = "mesh"
file = "ground.obj"
albedo = 0.3
albedo_map = "albedo.png"
[[world.bodies]]
name = "box"
shape = "mesh"
file = "quad_ascii.ply"
center_m = [0.0, 0.0, 0.5]
rotation_deg = [0.0, 0.0, 20.0]
albedo = 0.5
[sun]
direction = [0.4, -0.3, 0.8]
irradiance_w_m2 = 1361.0
[camera]
width = 48
height = 32
fx = 50.0
fy = 46.0
cx = 23.1
cy = 15.8
[trajectory]
kind = "line"
frames = 2
start_m = [0.5, -6.0, 4.0]
target_m = [0.0, 0.0, 0.3]
[render]
renderer = "mitsuba"
spp = 1
"""

RELOAD = r"""
import json, sys
import bpy
bpy.ops.wm.open_mainfile(filepath=sys.argv[1])
sc = bpy.context.scene
cam = sc.camera
imgs = [i for i in bpy.data.images if i.source != "VIEWER"]
print("RESULT " + json.dumps({
    "engine": sc.render.engine, "width": sc.render.resolution_x, "height": sc.render.resolution_y,
    "pixel_aspect_x": sc.render.pixel_aspect_x, "pixel_aspect_y": sc.render.pixel_aspect_y,
    "sensor_width_mm": cam.data.sensor_width, "lens_mm": cam.data.lens, "shift_x": cam.data.shift_x,
    "shift_y": cam.data.shift_y, "matrix": [list(r) for r in cam.matrix_world],
    "meshes": sorted(o.name for o in sc.objects if o.type == "MESH"),
    "scripts": [n.mode for m in bpy.data.materials if m.node_tree for n in m.node_tree.nodes if n.type == "SCRIPT"],
    "images_packed": [i.packed_file is not None for i in imgs],
    "paths": sorted(bpy.utils.blend_paths(absolute=False, local=True)),
}))
"""


def _save_blend_files(d):
    import cv2
    from mesh_fixtures import write_quad_box

    write_quad_box(d / "quad_ascii.ply")
    (d / "ground.obj").write_text("v -4 -4 0\nv 4 -4 0\nv 4 4 0\nv -4 4 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
                                  "f 1/1 2/2 3/3 4/4\n")
    cv2.imwrite(str(d / "albedo.png"), (np.indices((8, 8)).sum(0) % 2 * 155 + 100).astype(np.uint8))
    (d / "scene.toml").write_text(SAVE_BLEND_SCENE)


def test_save_blend_writes_a_blender_file_that_reloads(tmp_path):
    """--save-blend: a real .blend (magic BLENDER) of frame 0 that a fresh bpy opens with the same camera
    intrinsics and pose, one mesh object per body, OSL embedded, images packed, no temporary paths."""
    pytest.importorskip("bpy")
    pytest.importorskip("trimesh")
    import json
    import subprocess
    import sys

    from renderlab.cli import main
    from renderlab.geometry.camera import CameraModel as CM
    from renderlab.render.cycles_backend import BLENDER_CAM_FROM_CAM, blender_camera
    from renderlab.scenario import load_scenario
    from renderlab.worlds.base import frame_specs

    _save_blend_files(tmp_path)
    blend = tmp_path / "scene.blend"
    assert main(["render", str(tmp_path / "scene.toml"), "--out", str(tmp_path / "out"), "--renderer", "cycles",
                 "--save-blend", str(blend), "--quiet"]) == 0
    data = blend.read_bytes()
    assert data[:7] == b"BLENDER"
    assert b"renderlab-cycles-" not in data, "a path into the worker's temporary folder was saved"
    assert not (tmp_path / "scene.blend1").exists()
    res = subprocess.run([sys.executable, "-c", RELOAD, str(blend)], capture_output=True, text=True, timeout=300)
    line = [s for s in res.stdout.splitlines() if s.startswith("RESULT ")]
    assert line, res.stdout[-2000:] + res.stderr[-2000:]
    got = json.loads(line[0][7:])
    cam = CM.from_dict({"width": 48, "height": 32, "fx": 50.0, "fy": 46.0, "cx": 23.1, "cy": 15.8})
    for key, value in blender_camera(cam).items():
        assert got[key] == pytest.approx(value, rel=1e-6, abs=1e-6), key
    assert got["engine"] == "CYCLES" and got["meshes"] == ["box", "ground"]
    assert got["scripts"] == ["INTERNAL", "INTERNAL"] and got["images_packed"] == [True]
    assert not any("renderlab-cycles-" in p or p.startswith("/tmp") for p in got["paths"]), got["paths"]
    spec = frame_specs(*load_scenario(tmp_path / "scene.toml"))[0]  # the first frame's pose (origin at 0)
    M = np.array(got["matrix"])
    assert np.allclose(M[:3, :3], spec.pose.rotation.as_matrix() @ BLENDER_CAM_FROM_CAM, atol=1e-6)
    assert np.allclose(M[:3, 3], spec.pose.position_m, atol=1e-5)


def test_save_blend_without_cycles_is_a_one_line_error(tmp_path, capsys):
    from renderlab.cli import main

    _save_blend_files(tmp_path)
    (tmp_path / "there.blend").write_bytes(b"BLENDER")
    for extra, needle in [(["--save-blend", "x.blend"], "needs the Cycles renderer"),
                          (["--save-blend", "x.blend", "--renderer", "mitsuba"], "needs the Cycles renderer"),
                          (["--save-blend", "x.txt", "--renderer", "cycles"], "must end in .blend"),
                          (["--save-blend", "no/such/x.blend", "--renderer", "cycles"], "does not exist"),
                          (["--save-blend", "there.blend", "--renderer", "cycles"], "already exists")]:
        extra[1] = str(tmp_path / extra[1])
        argv = ["render", str(tmp_path / "scene.toml"), "--out", str(tmp_path / "out"), "--quiet", *extra]
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and needle in err[0], err
        assert not (tmp_path / "out").exists() and not (tmp_path / "x.blend").exists()
