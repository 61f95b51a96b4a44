"""The warm frame API (renderlab.Renderer): byte-for-byte equal to ``renderlab render``, poses in every supported
convention checked against OpenCV's projection, in-memory truth rows equal to the truth set's Parquet tables, and
one-line errors for bad requests."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pyarrow.parquet as pq
import pytest
from scipy.spatial.transform import Rotation
from tiny_ev5 import TINY_EV5_WORLD

from renderlab.errors import UserError

REPO = Path(__file__).resolve().parents[1]
ANALYTIC = REPO / "scenes" / "analytic_sphere_box.toml"
SMALL = ["camera.width=64", "camera.height=48", "camera.fx=66.0", "camera.fy=65.0", "camera.cx=32.3",
         "camera.cy=23.4", "render.spp=4", "trajectory.frames=3"]
EV5 = 'name = "frame_api_ev5"\n' + TINY_EV5_WORLD.replace("[world.site]\n", "[world.site]\nlod = true\n", 1) + """
[trajectory]
kind = "ev5_descent"
altitudes_m = [60.0, 25.0]
[camera]
width = 64
height = 64
fx = 300.0
fy = 300.0
cx = 31.5
cy = 31.5
[render]
spp = 2
near_clip_m = 0.01
"""


def _cli_render(scenario, out: Path, sets: list[str]) -> None:
    cmd = [sys.executable, "-m", "renderlab", "render", str(scenario), "--out", str(out)]
    for s in sets:
        cmd += ["--set", s]
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-2000:]


def _same_as_truthset(frame, ts, k):
    rec = ts.load(k)
    assert frame.dn.dtype == rec.dn.dtype and frame.dn.tobytes() == rec.dn.tobytes()
    assert frame.radiance.tobytes() == rec.radiance.tobytes()
    ch = frame.aovs.exr_channels()
    for name, a in (("P.X", rec.position[..., 0]), ("N.Z", rec.normal[..., 2]), ("range", rec.range)):
        assert ch[name].tobytes() == a.tobytes(), name
    np.testing.assert_array_equal(frame.aovs.body_id, rec.id)
    assert json.loads(json.dumps(frame.meta)) == {k2: v for k2, v in rec.meta.items()
                                                  if k2 not in ("index", "time_s", "exr", "dn", "dn_preview")}


def test_frame_equals_renderlab_render_byte_for_byte(tmp_path):
    """Every frame of the analytic scene from the API equals the truth set the command line wrote."""
    from renderlab import Renderer
    from renderlab.files.truthset import TruthSet

    _cli_render(ANALYTIC, tmp_path / "ts", SMALL)
    ts = TruthSet.open(tmp_path / "ts")
    with Renderer(ANALYTIC, overrides=SMALL) as r:
        assert r.n_frames == 3
        frames = [r.frame(k) for k in range(r.n_frames)]
        again = r.frame(1)
    for k, f in enumerate(frames):
        _same_as_truthset(f, ts, k)
    assert again.dn.tobytes() == frames[1].dn.tobytes()  # warm re-render of the same pose and seed


def test_ev5_frame_and_truth_rows_equal_the_truth_set(tmp_path, monkeypatch):
    """Tiled EV5 world: the frames and the landmark truth rows in memory equal the truth set's files."""
    from renderlab import Renderer
    from renderlab.files.truthset import TruthSet

    monkeypatch.setenv("RENDERLAB_CACHE", str(tmp_path / "cache"))
    scen = tmp_path / "ev5.toml"
    scen.write_text(EV5)
    _cli_render(scen, tmp_path / "ts", [])
    ts = TruthSet.open(tmp_path / "ts")
    table = pq.read_table(tmp_path / "ts" / "landmark_truth.parquet").to_pylist()
    with Renderer(scen) as r:
        frames = [r.frame(k) for k in range(r.n_frames)]
    rows = [row for f in frames for row in f.truth["landmark_truth"]]
    for k, f in enumerate(frames):
        _same_as_truthset(f, ts, k)
    assert len(rows) == len(table) > 0
    for a, b in zip(rows, table):
        assert set(a) == set(b)
        for c in b:
            same_nan = isinstance(b[c], float) and np.isnan(b[c]) and np.isnan(a[c])
            assert same_nan or a[c] == b[c], (c, a[c], b[c])


def _opencv_extrinsic():
    """A camera 9 m from the sphere of the analytic scene, as OpenCV's (rvec, tvec) and the lab's pose."""
    from renderlab.geometry.rotations import look_at

    eye, target = np.array([6.0, -6.5, 4.0]), np.array([-1.2, 0.6, 1.0])
    R_render_from_cam = look_at(eye, target, up=(0.0, 0.0, 1.0)).as_matrix()
    R_cam_from_render = R_render_from_cam.T
    tvec = -R_cam_from_render @ eye
    return cv2.Rodrigues(R_cam_from_render)[0], tvec, R_render_from_cam, eye


def test_pose_conventions_agree_with_opencv_projection():
    """The same pose as a 4x4 T_cam_from_render, a wxyz and an xyzw quaternion and a (position, R) pair gives the
    same image; every hit pixel's position AOV, projected by cv2.projectPoints with OpenCV's (rvec, tvec), lands
    on that pixel's centre within 0.01 px."""
    from renderlab import Renderer

    rvec, tvec, R, eye = _opencv_extrinsic()
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = cv2.Rodrigues(rvec)[0], tvec
    q = Rotation.from_matrix(R).as_quat()  # x, y, z, w
    poses = [
        (T, "cam_from_render"),
        ({"position_m": eye, "quaternion": [q[3], q[0], q[1], q[2]], "order": "wxyz"}, None),
        ({"position_m": eye, "quaternion": q, "order": "xyzw"}, None),
        ((eye, R), None),
    ]
    with Renderer(ANALYTIC, overrides=SMALL + ["render.pixel_filter=center"]) as r:
        images = []
        for pose, conv in poses:
            from renderlab import camera_pose

            images.append(r.frame(0, pose=camera_pose(pose, convention=conv), outputs=("radiance", "truth")))
        cam = r.plan.frames[0].camera
    for f in images[1:]:
        assert f.radiance.tobytes() == images[0].radiance.tobytes()
    P = images[0].aovs.position.reshape(-1, 3).astype(np.float64)
    hit = np.isfinite(P[:, 0])
    assert hit.mean() > 0.5
    K = np.array([[cam.fx, cam.skew, cam.cx], [0.0, cam.fy, cam.cy], [0.0, 0.0, 1.0]])
    uv = cv2.projectPoints(P[hit], rvec, tvec, K, None)[0].reshape(-1, 2)
    s, line = np.meshgrid(np.arange(cam.width), np.arange(cam.height))
    centres = np.stack([s.ravel(), line.ravel()], -1)[hit]
    # float32 positions at ~9 m: 1e-6 relative, ≈ 1e-4 px at fx 66
    assert np.abs(uv - centres).max() < 0.01


@pytest.mark.parametrize("kwargs, match", [
    ({"index": 7}, "frame index must be one of"),
    ({"index": 0, "pose": {"position_m": [0, 0, 5], "quaternion": [1, 0, 0, 0]}}, "order must declare"),
    ({"index": 0, "pose": {"position_m": [0, 0, np.nan], "R": np.eye(3)}}, "position_m must be 3 finite"),
    ({"index": 0, "pose": np.eye(3)}, "4x4 homogeneous"),
    ({"index": 0, "outputs": ("dn", "depth")}, "outputs must be"),
    ({"index": 0, "spp": 0}, "spp must be"),
    ({"index": 0, "sun": [0.0, 0.0, 0.0]}, "sun must be"),
])
def test_bad_requests_are_one_line_errors(kwargs, match):
    from renderlab import Renderer

    r = Renderer(ANALYTIC, overrides=SMALL)
    index = kwargs.pop("index")
    with pytest.raises(UserError, match=match) as err:
        r.frame(index, **kwargs)
    assert "\n" not in str(err.value)


def test_outputs_subset_and_spp_override():
    """``outputs`` leaves out what was not asked for; ``spp`` changes the frame's samples (and its radiance)."""
    from renderlab import Renderer

    with Renderer(ANALYTIC, overrides=SMALL) as r:
        f = r.frame(0, outputs=("radiance",))
        g = r.frame(0, outputs="radiance", spp=1)
    assert f.dn is None and f.aovs is None and f.truth == {} and f.radiance is not None
    assert f.radiance.tobytes() != g.radiance.tobytes()
    assert abs(float(f.radiance.mean()) / float(g.radiance.mean()) - 1) < 0.05


def test_auto_exposure_per_frame_and_saturation_recorded():
    """sensor.auto_exposure = "per_frame": each frame's exposure is exposure_for_peak of its own radiance (the former
    code documented this and silently kept frame 0's), and each record counts its saturated pixels."""
    from renderlab import Renderer
    from renderlab.sensor.model import exposure_for_peak

    with Renderer(ANALYTIC, overrides=SMALL + ["trajectory.azimuth_end_deg=120",
                                               'sensor.auto_exposure="per_frame"']) as r:
        frames = [r.frame(k) for k in range(r.n_frames)]
        want = [exposure_for_peak(f.radiance, r.options, fraction=r.scenario.sensor.auto_exposure_fraction)
                for f in frames]
        fixed = r.frame(1, exposure_s=2 * want[1])
    assert [f.exposure_s for f in frames] == want
    assert len(set(want)) == len(want)  # the scene's brightness changes along the orbit
    assert all(f.meta["sensor"]["exposure_s"] == f.exposure_s for f in frames)
    assert all(f.meta["sensor"]["saturated_px"] == f.saturated_px >= 0 for f in frames)
    assert fixed.exposure_s == 2 * want[1] and fixed.saturated_px >= frames[1].saturated_px


def test_a_world_whose_scene_follows_the_planned_pose_refuses_a_moved_camera():
    """Earth builds a tangent tile around each planned footprint: moving the camera would render the wrong tile."""
    from renderlab import Renderer

    r = Renderer(REPO / "scenes" / "earth_leo.toml", overrides=["camera.width=32", "camera.height=32",
                                                                "trajectory.frames=1"])
    p = r.spec(0).pose
    with pytest.raises(UserError, match="builds its scene around each planned pose"):
        r.frame(0, pose=(p.position_m + 10.0, p.rotation))


def test_default_auto_exposure_keeps_the_first_frames_exposure(tmp_path):
    """sensor.auto_exposure = true (documented now as it behaves): every frame of a truth set gets frame 0's."""
    from renderlab import Renderer
    from renderlab.files.truthset import TruthSet
    from renderlab.sensor.model import exposure_for_peak

    sets = SMALL + ["trajectory.azimuth_end_deg=120"]
    _cli_render(ANALYTIC, tmp_path / "ts", sets)
    ts = TruthSet.open(tmp_path / "ts")
    with Renderer(ANALYTIC, overrides=sets) as r:
        f0 = r.frame(0)
        t0 = exposure_for_peak(f0.radiance, r.options, fraction=r.scenario.sensor.auto_exposure_fraction)
    assert [fr["sensor"]["exposure_s"] for fr in ts.frames] == [t0] * 3


def test_frame_at_a_time_turns_the_ev5_sun_with_the_spin_and_is_seeded_by_time(tmp_path, monkeypatch):
    """Between planned frames, EV5's sun (body frame) is the planned sun turned about the spin pole by ω·Δt (checked
    against scipy's rotation of the planned frame-0 sun, independently of the world code); a planned frame's own time
    gives its sun; the same time and pose give the same bytes whatever was rendered in between."""
    from renderlab import Renderer

    monkeypatch.setenv("RENDERLAB_CACHE", str(tmp_path / "cache"))
    scen = tmp_path / "ev5.toml"
    scen.write_text(EV5)
    with Renderer(scen) as r:
        p0 = r.spec(0).pose
        omega = r.plan.model.spin.omega_rad_s
        s0 = np.asarray(r.spec(0).sun.direction_render)
        dt = 600.0
        a = r.frame(time_s=p0.time_s + dt, pose=p0, outputs=("dn", "truth"))
        r.frame(1)
        b = r.frame(time_s=p0.time_s + dt, pose=p0, outputs=("dn", "truth"))
        same = r.spec_at(r.spec(1).pose.time_s, r.spec(1).pose)
    want = Rotation.from_rotvec([0.0, 0.0, -omega * dt]).apply(s0)
    np.testing.assert_allclose(a.spec.sun.direction_render, want, atol=1e-12)
    np.testing.assert_allclose(same.sun.direction_render, r.spec(1).sun.direction_render, atol=1e-12)
    assert a.dn.tobytes() == b.dn.tobytes() and a.meta["ev5"]["altitude_m"] == pytest.approx(
        float(np.dot(p0.position_m - r.plan.model.site.origin_m, r.plan.model.site.R_body_from_site[:, 2])))
    assert a.truth["landmark_truth"] and a.time_s == p0.time_s + dt


def test_a_world_without_state_between_frames_refuses_a_time():
    """The Earth world (tiles per planned footprint) says so in one line instead of guessing."""
    from renderlab import Renderer

    r = Renderer(REPO / "scenes" / "earth_leo.toml", overrides=["camera.width=32", "camera.height=32",
                                                                "trajectory.frames=2"])
    with pytest.raises(UserError, match="no state between its planned"):
        r.frame(time_s=r.spec(0).pose.time_s + 1.0, pose=r.spec(0).pose)
