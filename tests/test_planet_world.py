"""The planet world and its centre/limb truth.

Oracles, each written here independently of ``renderlab.geometry.conic``:

* a sphere's limb in a pinhole camera is the section of its tangent cone (half-angle θ = asin(R/ρ), axis at α from the
  boresight): centre ``f·sin α cos α/(cos²α − sin²θ)`` from the principal point along the axis' image direction,
  semi-axes ``f·sin θ cos θ/(cos²α − sin²θ)`` (along it) and ``f·sin θ/√(cos²α − sin²θ)``;
* a triaxial ellipsoid's limb passes through the projections of its tangency points — the intersection of the body
  with the polar plane of the camera (``cᵀA x = 1``), a circle in the space where the body is the unit sphere —
  through which ``cv2.fitEllipse`` draws the ellipse;
* in a Mitsuba render at zero phase, the body's pixels (id AOV) have the limb conic's centre as centroid and its
  area π·a·b (the principal point dithered over a 4×4 sub-pixel grid to beat the pixel lattice).
"""

from __future__ import annotations

import csv
import dataclasses

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from renderlab.dynamics.camera_paths import CameraPose
from renderlab.errors import UserError
from renderlab.geometry.camera import CameraModel
from renderlab.render.scene import FrameSpec, SunSpec
from renderlab.worlds.planet.body import build_body
from renderlab.worlds.planet.config import PlanetWorld
from renderlab.worlds.planet.truth import centre_truth_row

cv2 = pytest.importorskip("cv2")


def scene(world: dict, traj: dict, *, size: int = 256, f: float = 600.0, spp: int = 1, **extra) -> dict:
    return {"name": "planet_test", "world": {"kind": "planet", **world}, "sun": {"direction": [1.0, 0.0, 0.0]},
            "camera": {"width": size, "height": size, "fx": f, "fy": f, "cx": (size - 1) / 2, "cy": (size - 1) / 2},
            "trajectory": traj, "render": {"spp": spp, "far_clip_m": 1e9, "pixel_filter": "center"}, **extra}


def spec(camera, position, R=None, sun=(0.0, 0.0, 1.0)) -> FrameSpec:
    rot = Rotation.identity() if R is None else Rotation.from_matrix(R)
    return FrameSpec(index=0, pose=CameraPose(0.0, np.asarray(position, float), rot), camera=camera,
                     sun=SunSpec(np.asarray(sun, float) / np.linalg.norm(sun), 1361.0))


def test_sphere_limb_conic_is_the_tangent_cone_closed_form():
    f, R = 800.0, 3.0e6
    cam = CameraModel(width=1024, height=1024, fx=f, fy=f, cx=511.5, cy=511.5)
    body = build_body(PlanetWorld(preset="custom", semi_axes_m=[R] * 3))
    rng = np.random.default_rng(1)
    for _ in range(40):
        a, phi = np.radians(rng.uniform(0.5, 25.0)), rng.uniform(-np.pi, np.pi)
        th = np.radians(rng.uniform(1.0, 20.0))
        rho = R / np.sin(th)
        d = np.array([np.sin(a) * np.cos(phi), np.sin(a) * np.sin(phi), np.cos(a)])
        row = centre_truth_row(spec(cam, -rho * d), body)       # camera frame = render frame, body at the origin
        D = np.cos(a) ** 2 - np.sin(th) ** 2
        c = f * np.sin(a) * np.cos(a) / D
        assert abs(row["limb_centre_s"] - (511.5 + c * np.cos(phi))) <= 1e-6
        assert abs(row["limb_centre_l"] - (511.5 + c * np.sin(phi))) <= 1e-6
        assert abs(row["limb_a_px"] - f * np.sin(th) * np.cos(th) / D) <= 1e-6
        assert abs(row["limb_b_px"] - f * np.sin(th) / np.sqrt(D)) <= 1e-6
        assert abs((row["limb_angle_rad"] - phi + np.pi / 2) % np.pi - np.pi / 2) <= 1e-9
        assert abs(row["centre_s"] - (511.5 + f * np.tan(a) * np.cos(phi))) <= 1e-6   # projected centre
        assert row["range_m"] == pytest.approx(rho, rel=1e-12) and row["limb_model"] == "ellipsoid"


def test_ellipsoid_limb_conic_passes_through_the_projected_tangency_points():
    cam = CameraModel(width=640, height=480, fx=700.0, fy=690.0, cx=330.2, cy=236.8, skew=1.5)
    world = PlanetWorld(preset="custom", semi_axes_m=[3.0e6, 2.2e6, 1.6e6], rotation_deg=[25.0, -40.0, 70.0])
    body = build_body(world)
    R_rp = body.R_render_from_principal
    rng = np.random.default_rng(7)
    for _ in range(10):
        c = Rotation.random(random_state=rng).apply([0.0, 0.0, 1.0]) * rng.uniform(12e6, 40e6)
        R = Rotation.from_rotvec(rng.normal(size=3) * 0.1).as_matrix() @ _look(c)
        row = centre_truth_row(spec(cam, c, R), body)
        cp = np.diag(1 / body.semi_axes_m) @ R_rp.T @ c          # camera in the unit-sphere space
        n = cp / np.linalg.norm(cp)
        e1 = np.cross(n, [0.3, 0.5, 0.8])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(n, e1)
        t = np.linspace(0, 2 * np.pi, 720, endpoint=False)[:, None]
        y = cp / (cp @ cp) + np.sqrt(1 - 1 / (cp @ cp)) * (np.cos(t) * e1 + np.sin(t) * e2)  # |y| = 1, cpᵀy = 1
        p = (y * body.semi_axes_m) @ R_rp.T                       # tangency points, render frame
        sl = cam.project((p - c) @ R)
        (cx, cy), (w, h), ang = cv2.fitEllipse(sl.astype(np.float32))
        assert np.hypot(cx - row["limb_centre_s"], cy - row["limb_centre_l"]) <= 2e-3
        assert sorted([w / 2, h / 2]) == pytest.approx([row["limb_b_px"], row["limb_a_px"]], abs=2e-3)
        r = R.T @ (body.centre_m - c)
        M = np.array([[row["cone_xx"], row["cone_xy"], row["cone_xz"]], [row["cone_xy"], row["cone_yy"], row["cone_yz"]],
                      [row["cone_xz"], row["cone_yz"], row["cone_zz"]]])
        rays = (p - c) @ R
        rays /= np.linalg.norm(rays, axis=1, keepdims=True)
        assert np.abs(np.einsum("ij,jk,ik->i", rays, M, rays)).max() <= 1e-12  # the limb rays lie on the cone
        assert r @ M @ r > 0


def _look(c) -> np.ndarray:
    from renderlab.geometry.rotations import look_at

    return look_at(c, np.zeros(3), [0.0, 0.0, 1.0] if abs(c[2]) < 0.9 * np.linalg.norm(c) else [1.0, 0.0, 0.0]).as_matrix()


@pytest.mark.parametrize("world", [{"preset": "custom", "semi_axes_m": [1.0e6] * 3},
                                   {"preset": "custom", "semi_axes_m": [1.0e6, 0.8e6, 0.7e6],
                                    "rotation_deg": [20.0, 30.0, 40.0], "mesh_level": 6}], ids=["sphere", "ellipsoid"])
def test_id_aov_disc_centroid_and_area_match_the_limb_conic(world):
    from renderlab import Renderer
    from renderlab.scenario import scenario_from_dict

    traj = {"kind": "planet_approach", "range_start_m": 12.0e6, "phase_start_deg": 0.0, "offset_deg": [6.0, -4.0]}
    with Renderer(scenario_from_dict(scene({**world, "law": "lambert"}, traj))) as r:
        cam0 = r.spec(0).camera
        row = r.frame(0, outputs=("truth",)).truth["centre_truth"][0]
        assert row["limb_in_image"] and row["phase_deg"] == pytest.approx(0.0, abs=1e-9)
        centroids, areas = [], []
        for dx in (np.arange(4) + 0.5) / 4 - 0.5:
            for dy in (np.arange(4) + 0.5) / 4 - 0.5:
                f = r.frame(0, camera=dataclasses.replace(cam0, cx=cam0.cx + dx, cy=cam0.cy + dy), outputs=("truth",))
                ll, ss = np.nonzero(f.aovs.body_id == 0)
                centroids.append([ss.mean() - dx, ll.mean() - dy])
                areas.append(len(ss))
    centre = np.mean(centroids, axis=0)
    limb = np.array([row["limb_centre_s"], row["limb_centre_l"]])
    assert np.hypot(*(centre - limb)) <= 0.02
    assert abs(np.sqrt(np.mean(areas) / np.pi) - row["apparent_radius_px"]) <= 0.02
    assert np.hypot(row["centre_s"] - limb[0], row["centre_l"] - limb[1]) > 0.4   # off-axis: not the projected centre


def test_truth_set_writes_centre_truth_with_the_registered_schema(tmp_path):
    import pyarrow.parquet as pq

    from renderlab.contracts.schemas import CENTRE_TRUTH
    from renderlab.pipeline import render_truthset
    from renderlab.scenario import scenario_from_dict

    traj = {"kind": "planet_approach", "frames": 2, "range_start_m": 3.0e7, "range_end_m": 2.0e7,
            "phase_start_deg": 20.0, "phase_end_deg": 80.0, "offset_deg": [1.0, 2.0]}
    sc = scenario_from_dict(scene({"preset": "moon"}, traj, size=32, f=60.0, spp=2))
    table = pq.read_table(render_truthset(sc, tmp_path, tmp_path / "moon", progress=False) / "centre_truth.parquet")
    assert table.schema.equals(CENTRE_TRUTH), table.schema
    rows = table.to_pylist()
    assert [r["range_m"] for r in rows] == pytest.approx([3.0e7, 2.0e7], rel=1e-12)
    assert [r["phase_deg"] for r in rows] == pytest.approx([20.0, 80.0], abs=1e-9)
    assert [r["centre_s"] for r in rows] == pytest.approx([15.5 + 60 * np.tan(np.radians(1.0))] * 2, abs=1e-9)
    assert [r["centre_l"] for r in rows] == pytest.approx([15.5 + 60 * np.tan(np.radians(2.0))] * 2, abs=1e-9)


def test_presets_shapes_and_one_line_errors():
    from renderlab.scenario import scenario_from_dict

    moon, mars = build_body(PlanetWorld(preset="moon")), build_body(PlanetWorld(preset="mars", mesh_level=4))
    assert moon.spec.shape == "sphere" and moon.spec.radius_m == 1737.4e3
    assert mars.spec.shape == "trimesh" and list(mars.semi_axes_m) == [3396.19e3, 3396.19e3, 3376.20e3]
    v = mars.spec.vertices
    r_ell = np.sqrt(np.sum((v / mars.semi_axes_m) ** 2, axis=1))          # 1 on the ellipsoid
    assert 1.0 <= r_ell.min() and r_ell.max() <= 1.0 + 5e-4               # pushed out by the mean chord dip only
    ev5 = build_body(PlanetWorld(preset="ev5", ev5_facet_m=20.0))
    half = np.sort(np.ptp(ev5.spec.vertices, axis=0) / 2)
    assert ev5.limb_model == "equivalent_ellipsoid"
    assert np.sort(ev5.semi_axes_m) == pytest.approx(half, rel=0.1)   # the inertia-equivalent ellipsoid ~ the extents
    traj = {"kind": "planet_approach", "range_start_m": 1.0e6}
    for world, msg in [({"preset": "custom"}, "semi_axes_m"), ({"preset": "ev5", "semi_axes_m": [1.0, 1, 1]}, "ev5"),
                       ({"preset": "jupiter"}, "preset")]:
        with pytest.raises(UserError, match=msg):
            scenario_from_dict(scene(world, traj))
    from renderlab.worlds.base import make_plan

    with pytest.raises(UserError, match="inside the body"):
        make_plan(scenario_from_dict(scene({"preset": "moon"}, traj)), ".")
    far = scene({"preset": "moon"}, {"kind": "planet_approach", "range_start_m": 2e7})
    far["render"]["far_clip_m"] = 1e7
    with pytest.raises(UserError, match="far_clip_m"):
        make_plan(scenario_from_dict(far), ".")


def test_render_origin_moves_where_the_camera_looks_in_low_orbit():
    from renderlab import Renderer
    from renderlab.scenario import scenario_from_dict
    from renderlab.worlds.base import make_plan
    from renderlab.worlds.planet.path import float32_bound_px

    low = {"kind": "planet_approach", "range_start_m": 6378137.0 + 4.0e5, "phase_start_deg": 30.0}
    sc = scenario_from_dict(scene({"preset": "earth", "mesh_level": 6}, low, size=32, f=20000.0))
    plan = make_plan(sc, ".")
    origin = np.asarray(plan.static_scene.origin_m)
    nadir = plan.frames[0].pose.position_m / np.linalg.norm(plan.frames[0].pose.position_m)
    assert float32_bound_px(plan.frames[0], plan.body, np.zeros(3)) > 0.01        # 2^-24·|c|·f/h at the centre
    assert np.linalg.norm(origin - 6378137.0 * nadir) < 30e3                      # the boresight's hit (nadir)
    assert plan.info["float32_bound_px"] <= 0.01
    with Renderer(sc) as r:                                                       # positions come back in the frame
        P = r.frame(0, outputs=("truth",)).aovs.position.reshape(-1, 3).astype(float)
    assert np.abs(np.sqrt(np.sum((P / plan.body.semi_axes_m) ** 2, axis=1)) - 1).max() < 1e-4
    far = {"kind": "planet_approach", "range_start_m": 4.0e7, "phase_start_deg": 30.0}
    plan = make_plan(scenario_from_dict(scene({"preset": "earth", "mesh_level": 4}, far, f=20000.0)), ".")
    assert np.array_equal(plan.static_scene.origin_m, np.zeros(3))


def test_table_trajectory_flies_the_planet_world(tmp_path):
    from renderlab.scenario import scenario_from_dict
    from renderlab.worlds.base import make_plan

    pos = np.array([[2.0e7, 1.0e6, 3.0e6], [1.9e7, 2.0e6, 2.0e6], [1.8e7, 3.0e6, 1.0e6]])
    rots = [Rotation.from_matrix(_look(p)) for p in pos]
    with open(tmp_path / "traj.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["time_s", "x_m", "y_m", "z_m", "qx", "qy", "qz", "qw"])
        for t, p, q in zip([0.0, 10.0, 20.0], pos, rots):
            w.writerow([repr(t), *map(repr, p), *map(repr, q.as_quat())])
    traj = {"kind": "table", "file": "traj.csv", "frame": "PLANET_FIXED", "times_s": [0.0, 10.0, 20.0],
            "quaternion_order": "xyzw", "quaternion_direction": "cam_to_frame"}
    plan = make_plan(scenario_from_dict(scene({"preset": "moon"}, traj)), tmp_path)
    for f, p, q in zip(plan.frames, pos, rots):
        assert np.allclose(f.pose.position_m, p, rtol=0, atol=1e-6)
        assert (f.pose.rotation * q.inv()).magnitude() < 1e-9
        row = plan.frame_rows(f, None)["centre_truth"][0]
        assert np.hypot(row["centre_s"] - 127.5, row["centre_l"] - 127.5) < 1e-6   # looks at the centre
