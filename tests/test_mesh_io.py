"""The one mesh reader (:mod:`renderlab.render.mesh_io`): formats, quads, units, normals, validation.

Files are written by trimesh's own exporters (OBJ, PLY ASCII and binary, STL ASCII and binary, GLB: those
write triangles) and, for the quad-faced box that trimesh cannot export, as plain quad OBJ/PLY text and
binary records. Oracle: a unit box has 8 distinct corners, 12 triangles, volume 1 m³ and is watertight;
an icosphere's smooth normals point radially.
"""

from __future__ import annotations

import numpy as np
import pytest
from mesh_fixtures import BOX_QUADS, BOX_V, write_quad_box, write_trimesh

from renderlab.errors import UserError
from renderlab.render.mesh_io import load_mesh, smooth_normals

trimesh = pytest.importorskip("trimesh")

def _box_files(d):
    box = trimesh.Trimesh(BOX_V, np.vstack([BOX_QUADS[:, [0, 1, 2]], BOX_QUADS[:, [2, 3, 0]]]), process=False)
    return {
        "quad.obj": write_quad_box(d / "quad.obj"),
        "quad_ascii.ply": write_quad_box(d / "quad_ascii.ply"),
        "quad_binary.ply": write_quad_box(d / "quad_binary.ply", encoding="binary_little_endian"),
        "tri.obj": write_trimesh(d / "tri.obj", box),
        "tri_ascii.ply": write_trimesh(d / "tri_ascii.ply", box, encoding="ascii"),
        "tri_binary.ply": write_trimesh(d / "tri_binary.ply", box, encoding="binary"),
        "binary.stl": write_trimesh(d / "binary.stl", box),
        "ascii.stl": (d / "ascii.stl").write_text(trimesh.exchange.stl.export_stl_ascii(box)) and d / "ascii.stl",
        "box.glb": write_trimesh(d / "box.glb", box),
    }


def _volume(m):
    T = m.vertices[m.faces]
    return float(np.einsum("ij,ij->i", T[:, 0], np.cross(T[:, 1], T[:, 2])).sum() / 6.0)


def test_every_format_reads_the_same_box(tmp_path):
    """OBJ, PLY (ASCII/binary, quads or triangles), STL (ASCII/binary), GLB → 12 outward triangles, 1 m³."""
    for name, path in _box_files(tmp_path).items():
        m = load_mesh(path)
        assert m.faces.shape == (12, 3) and m.n_degenerate == 0, name
        assert len(np.unique(m.vertices, axis=0)) == 8 and np.allclose(np.abs(m.vertices), 0.5), name
        assert abs(_volume(m) - 1.0) < 1e-6, name  # winding kept: counter-clockwise seen from outside
        assert m.watertight and m.vertex_normals is None, name


def test_units_and_scale(tmp_path):
    km = load_mesh(write_quad_box(tmp_path / "km.ply", 0.002), units="km")  # a 2 m box written in km
    cm = load_mesh(write_trimesh(tmp_path / "cm.stl", trimesh.creation.box((200.0, 200.0, 200.0))), units="cm")
    assert np.allclose(km.vertices.max(0) - km.vertices.min(0), 2.0)
    assert np.allclose(cm.vertices.max(0) - cm.vertices.min(0), 2.0)
    assert np.allclose(load_mesh(tmp_path / "km.ply", units="km", scale=0.5).vertices, km.vertices * 0.5)
    with pytest.raises(UserError, match="units"):
        load_mesh(tmp_path / "km.ply", units="mm")


def test_smooth_normals_are_radial_on_a_sphere_and_shared_at_coincident_vertices(tmp_path):
    ico = trimesh.creation.icosphere(subdivisions=3, radius=2.0)
    for path in (write_trimesh(tmp_path / "ico.obj", ico), write_trimesh(tmp_path / "ico.stl", ico)):
        m = load_mesh(path, normals="smooth")
        radial = m.vertices / np.linalg.norm(m.vertices, axis=1, keepdims=True)
        cos = np.einsum("ij,ij->i", m.vertex_normals, radial)
        assert cos.min() > 0.999, (path.name, cos.min())  # STL: 3 copies per corner, one normal each
        assert np.allclose(np.linalg.norm(m.vertex_normals, axis=1), 1.0)
        assert m.watertight
    # a flat split square: the two triangles' normals agree, so smooth = flat there
    V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.0]])
    assert np.allclose(smooth_normals(V, np.array([[0, 1, 2], [0, 2, 3]])), [0, 0, 1])


def test_degenerate_faces_are_removed_and_counted(tmp_path):
    p = tmp_path / "degen.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nv 5 5 5\n"
                 "f 1 2 3\nf 1 2 2\nf 1 2 4\n")  # good, repeated vertex, collinear; vertex 5 unreferenced
    m = load_mesh(p)
    assert m.n_degenerate == 2 and m.faces.tolist() == [[0, 1, 2]] and len(m.vertices) == 3
    assert not m.watertight


def test_uv_follow_the_labs_convention(tmp_path):
    """OBJ vt (image bottom at v = 0) → the lab's v from the map's top row down: v_lab = 1 − v."""
    p = tmp_path / "uv.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 1 0.25\nf 1/1 2/2 3/3\n")
    m = load_mesh(p)
    order = np.lexsort(m.vertices.T[::-1])
    assert np.allclose(m.vertex_uv[order], [[0, 1], [1, 1], [1, 0.75]])


@pytest.mark.parametrize("name, text, needle", [
    ("missing.obj", None, "mesh not found"),
    ("rock.xyz", "1 2 3\n", "not a supported mesh file"),
    ("empty.stl", "solid rock\nendsolid rock\n", "has no faces"),
    ("broken.obj", "v 1 2\nf 1 2 3\n", "cannot read broken.obj as OBJ"),
    ("nan.obj", "v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n", "non-finite"),
    ("line.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n", "only degenerate faces"),
    ("junk.glb", "hello", "cannot read junk.glb as GLB"),
    ("junk.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n", "junk.ply"),
])
def test_bad_files_are_one_line_user_errors(tmp_path, name, text, needle):
    if text is not None:
        (tmp_path / name).write_text(text)
    with pytest.raises(UserError, match=needle) as ei:
        load_mesh(tmp_path / name, where="world.bodies.1.file")
    assert "\n" not in str(ei.value) and str(ei.value).startswith("world.bodies.1.file: ")


def test_scenario_keys_units_and_normals():
    from renderlab.scenario import BodyConfig

    b = BodyConfig(name="m", shape="mesh", file="x.ply", units="km", normals="smooth")
    assert (b.units, b.normals) == ("km", "smooth")
    with pytest.raises(ValueError, match="apply to shape 'mesh' only"):
        BodyConfig(name="s", shape="sphere", radius_m=1.0, units="km")
    with pytest.raises(ValueError):
        BodyConfig(name="m", shape="mesh", file="x.ply", normals="phong")


def test_ev5_shape_files_go_through_the_same_reader(tmp_path):
    """The EV5 world reads STL and GLB (and quad PLY) through mesh_io, km → m, faces turned outward."""
    from renderlab.worlds.ev5.shape import load_shape_file

    ico = trimesh.creation.icosphere(subdivisions=3, radius=0.2)  # km
    ico.invert()  # inward winding on purpose
    for path in (write_trimesh(tmp_path / "s.stl", ico), write_trimesh(tmp_path / "s.glb", ico),
                 write_quad_box(tmp_path / "b.ply", 0.1, "binary_little_endian")):
        shape = load_shape_file(path, "km")
        assert shape.volume() > 0, path.name
        expect = 1e6 if path.suffix == ".ply" else ico.volume * -1e9
        assert abs(shape.volume() / expect - 1) < 1e-6, path.name
