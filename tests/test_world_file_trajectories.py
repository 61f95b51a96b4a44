"""File trajectories drive every world: EV5, Earth and microsat flown on an OEM, a SPICE SPK/CK pair and a CSV table.

Each world gets a known trajectory, written three ways by independent writers: an OEM by the ``oem`` package (no
attitude: EV5 and microsat point with ``attitude = "look_at"``, Earth takes its default nadir pointing), an SPK
(type 13) and CK (type 3) by spiceypy, with the world's frame a text-kernel alias of J2000, and a CSV by the
``csv`` module. Each scenario is rendered by Mitsuba at 32×32 through :func:`renderlab.pipeline.render_truthset` and
read back with ``json`` and ``OpenEXR`` only.

Oracles: the manifest's per-frame pose, time and epoch equal the file's states (EV5: the pose itself, in
EV5_FIXED; microsat: the LVLH state with the manifest's tumble, ``position_body = Rᵀ p``; Earth: the GCRF state,
its ITRS image by astropy, and the GCRF → ITRF rotation by astropy applied to the attitude); attitudes the file
does not give are rebuilt here (look-at, nadir from r and v). Every rendered surface point (position AOV) lands,
through ``cv2.projectPoints`` of the file's pose, on its own pixel centre; the EV5 and microsat body centres
project onto their bodies, the Earth's sub-satellite point (geodetic, by a fixed-point inversion written here) is
where the position AOV interpolated at OpenCV's pixel says. The sun: EV5's turns with the spin from ``[sun]`` at
time 0, the microsat's from ``world.sun_lvlh`` with the mean motion; frame 0 at time 0 carries the tumble's q0.
Bad inputs (a frame the world cannot use, no attitude, no epochs for the Earth) are one line, exit 2, nothing
written. A plug-in world that declares the file kinds (``renderlab.scenario.kinds.FILE_TRAJECTORIES``) flies one
through ``frame_specs``; without them the scenario is refused.
"""

from __future__ import annotations

import numpy as np
import pytest
from file_trajectory_fixtures import (  # noqa: I001
    BAD,
    CAMERA,
    CSV_REL,
    EV5_AIM,
    MICROSAT_AIM,
    MU,
    Q0,
    RE,
    SOURCES,
    SUN0_EV5,
    T_FRAMES,
    T_SAMPLES,
    TINY_EV5_WORLD,
    WGS_F,
    assert_epochs,
    bilinear,
    earth_truth,
    ev5_truth,
    gcrs_to_itrs,
    geodetic_ssp,
    iso,
    microsat_truth,
    nadir_R,
    project,
    quat_R,
    render,
    reprojection_px,
    rot_angle,
    trajectory_block,
    write_csv,
    write_oem,
)
from scipy.spatial.transform import Rotation


# ---------------------------------------------------------------------- EV5
@pytest.mark.parametrize("kind", SOURCES)
def test_ev5_flies_a_file_trajectory(tmp_path, kind):
    pos, vel, rots = ev5_truth(T_SAMPLES)
    quat = write_csv(tmp_path / "traj.csv", pos, vel, rots) if kind == "table" else ""
    block = trajectory_block(kind, tmp_path, "EV5_FIXED", "RL_EV5", -998, ev5_truth, EV5_AIM, [0, 0, 1]) + quat
    text = (f'name = "ev5_file"\n{TINY_EV5_WORLD}[sun]\ndirection = {list(SUN0_EV5)}\n{CAMERA.format(f=30.0)}'
            '[render]\nspp = 1\nnear_clip_m = 1.0\nfar_clip_m = 100000.0\n' + block)
    frames, chans = render(tmp_path, text)
    assert_epochs(frames)
    omega = 2 * np.pi / (3.725 * 3600)
    s0 = SUN0_EV5 / np.linalg.norm(SUN0_EV5)
    for k, (rec, ch) in enumerate(zip(frames, chans)):
        i = int(np.flatnonzero(T_SAMPLES == T_FRAMES[k])[0])
        assert np.abs(np.array(rec["pose"]["position_m"]) - pos[i]).max() < 1e-6
        assert rot_angle(quat_R(rec["pose"]["quat_render_from_cam_xyzw"]), rots[i]) < 1e-9
        sun = Rotation.from_rotvec([0, 0, -omega * T_FRAMES[k]]).apply(s0)  # inertially fixed, body spins about +z
        assert np.abs(np.array(rec["sun"]["direction_render"]) - sun).max() < 1e-12
        assert np.allclose(rec["ev5"]["sun_direction_eclip"], frames[0]["ev5"]["sun_direction_eclip"], atol=1e-12)
        assert "spin_matched" not in rec["ev5"]
        assert reprojection_px(ch, rots[i], pos[i], rec) < 1e-3
        s, ln = np.rint(project([[0.0, 0, 0]], rots[i], pos[i], rec)[0]).astype(int)
        assert ch["id"][ln, s] >= 0, "the body centre projects onto the body"



# ---------------------------------------------------------------------- microsat
@pytest.mark.parametrize("kind", SOURCES)
def test_microsat_flies_a_file_trajectory(tmp_path, kind):
    pos, vel, rots = microsat_truth(T_SAMPLES)
    quat = write_csv(tmp_path / "traj.csv", pos, vel, rots, wxyz_frame_to_cam=True) if kind == "table" else ""
    block = trajectory_block(kind, tmp_path, "LVLH", "RL_TARGET", -998, microsat_truth, MICROSAT_AIM, [1, 0, 0]) + quat
    text = ('name = "microsat_file"\n[world]\nkind = "microsat"\nsun_lvlh = [0.4, 0.7, 0.5]\n[world.tumble]\n'
            f'q0_lvlh_from_body_xyzw = {list(Q0)}\nomega0_body_deg_s = [2.0, -3.0, 1.0]\naltitude_m = 500000.0\n'
            f'{CAMERA.format(f=60.0)}[render]\nspp = 1\nnear_clip_m = 0.01\nfar_clip_m = 1000.0\n' + block)
    frames, chans = render(tmp_path, text)
    assert_epochs(frames)
    n = np.sqrt(MU / (RE + 500e3) ** 3)
    s0 = np.array([0.4, 0.7, 0.5]) / np.linalg.norm([0.4, 0.7, 0.5])
    assert rot_angle(quat_R(frames[0]["microsat"]["quat_lvlh_from_body_xyzw"]), quat_R(Q0 / np.linalg.norm(Q0))) < 1e-12
    for k, (rec, ch) in enumerate(zip(frames, chans)):
        i = int(np.flatnonzero(T_SAMPLES == T_FRAMES[k])[0])
        m = rec["microsat"]
        R_lb = quat_R(m["quat_lvlh_from_body_xyzw"])
        assert np.abs(np.array(m["r_lvlh_m"]) + pos[i]).max() < 1e-9     # the target relative to the camera
        assert np.abs(np.array(m["v_lvlh_mps"]) + vel[i]).max() < 1e-9
        assert rot_angle(quat_R(m["quat_lvlh_from_cam_xyzw"]), rots[i]) < 1e-9
        p_b, R_bc = R_lb.T @ pos[i], R_lb.T @ rots[i]
        assert np.abs(np.array(rec["pose"]["position_m"]) - p_b).max() < 1e-9
        assert rot_angle(quat_R(rec["pose"]["quat_render_from_cam_xyzw"]), R_bc) < 1e-9
        sun_lvlh = Rotation.from_rotvec([0, 0, -n * T_FRAMES[k]]).apply(s0)   # inertially fixed, LVLH turns at n
        assert np.abs(np.array(rec["sun"]["direction_render"]) - R_lb.T @ sun_lvlh).max() < 1e-9
        assert reprojection_px(ch, R_bc, p_b, rec) < 1e-3
        s, ln = np.rint(project([[0.0, 0, 0]], R_bc, p_b, rec)[0]).astype(int)
        assert ch["id"][ln, s] >= 0, "the target's centre of mass projects onto the target"



@pytest.mark.parametrize("kind", SOURCES)
def test_earth_flies_a_file_trajectory(tmp_path, kind):
    pos, vel, rots = earth_truth(T_SAMPLES)
    stamps = [iso(t) for t in T_SAMPLES]
    r_i, v_i, M = gcrs_to_itrs(pos, vel, stamps)
    if kind == "ccsds":                    # positions only: the world's nadir pointing
        rots = [nadir_R(r, v) for r, v in zip(pos, vel)]
    quat = ""
    if kind == "table":                    # in ITRF: the world converts back
        quat = write_csv(tmp_path / "traj.csv", r_i, v_i, [m @ R for m, R in zip(M, rots)], wxyz_frame_to_cam=True)
    frame = "ITRF" if kind == "table" else "GCRF"
    block = trajectory_block(kind, tmp_path, frame, "EARTH", 399, earth_truth) + quat
    f = 16.0 / np.tan(np.radians(10.0))
    text = ('name = "earth_file"\n[world]\nkind = "earth"\ntile_grid = 8\nantialias = 1\ncoast_db_tolerance_m = '
            f'2000.0\n{CAMERA.format(f=f)}[render]\nspp = 1\nnear_clip_m = 1000.0\nfar_clip_m = 1e7\n' + block)
    frames, chans = render(tmp_path, text)
    assert_epochs(frames)
    for k, (rec, ch) in enumerate(zip(frames, chans)):
        i = int(np.flatnonzero(T_SAMPLES == T_FRAMES[k])[0])
        s = rec["spacecraft"]
        # GCRF in: the file's own state, but for the ccsds and table epochs (UTC labels) the frame instant is
        # epoch0 + t in TDB seconds (sources.py), 2.6 ns away after 8 s: 20 µm at 7.3 km/s. ITRF in: the lab's ERFA
        # chain vs astropy's (mm)
        tol = (1e-6 if kind == "spice" else 1e-4) if frame == "GCRF" else 0.01
        assert np.abs(np.array(s["r_eci_m"]) - pos[i]).max() < tol
        assert np.abs(np.array(s["v_eci_mps"]) - vel[i]).max() < (1e-6 if frame == "GCRF" else 2e-3)
        assert np.abs(np.array(s["r_ecef_m"]) - r_i[i]).max() < 0.01
        # the lab leaves the precession-nutation, LOD and polar-motion rates out of v_ITRF (orientation.py: ≤ 1 mm/s)
        assert np.abs(np.array(s["v_ecef_mps"]) - v_i[i]).max() < 2e-3
        R_ecef_cam = M[i] @ rots[i]
        assert rot_angle(quat_R(s["quat_ecef_from_cam_xyzw"]), R_ecef_cam) < 1e-8
        rf = rec["render_frame"]
        R_er, o = np.array(rf["R_ecef_from_render"]), np.array(rf["origin_ecef_m"])
        assert np.abs(R_er @ rec["pose"]["position_m"] + o - r_i[i]).max() < 0.01
        def to_ecef(P, R_er=R_er, o=o):
            return P @ R_er.T + o

        assert reprojection_px(ch, R_ecef_cam, r_i[i], rec, to_ecef) < 1e-3
        # the sub-satellite point is where OpenCV puts it: the rendered surface there is the ssp, but for the ground
        # facets' chord sag (the tile mesh is 8×8 cells of 48 px / 8 · GSD; its vertices lie on the ellipsoid)
        ssp = geodetic_ssp(r_i[i])
        (u, w), = project([ssp], R_ecef_cam, r_i[i], rec)
        d = to_ecef(np.array([bilinear(ch[c], u, w) for c in ("P.X", "P.Y", "P.Z")])) - ssp
        up = (r_i[i] - ssp) / np.linalg.norm(r_i[i] - ssp)
        gsd = np.linalg.norm(r_i[i] - ssp) / f
        sag = (np.sqrt(2) * 48 / 8 * gsd) ** 2 / (8 * RE * (1 - WGS_F) ** 2)   # chord sag, R ≥ b²/a
        assert np.linalg.norm(d - (d @ up) * up) < 5.0 and -sag < d @ up <= 0.0, (d, sag)



@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_file_trajectories_are_one_line(tmp_path, capsys, case):
    from renderlab.cli import main

    world, traj, oem_frame, needle = BAD[case]
    (tmp_path / "t.csv").write_text(CSV_REL)
    if oem_frame is not None:
        pytest.importorskip("oem")
        pos, vel, _ = earth_truth(T_SAMPLES)
        write_oem(tmp_path / "t.oem", oem_frame, "EARTH", pos, vel)
    (tmp_path / "bad.toml").write_text(f'name = "bad"\n{world}{CAMERA.format(f=30.0)}{traj}')
    rc = main(["render", str(tmp_path / "bad.toml"), "--out", str(tmp_path / "out"), "--quiet"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and err.count("\n") == 0 and err.startswith("renderlab: error: ") and needle in err, err
    assert not (tmp_path / "out").exists() and not list(tmp_path.glob(".out*"))



# ---------------------------------------------------------------------- a plug-in world declares the file kinds
def test_plugin_world_that_declares_file_trajectories_flies_one(tmp_path):
    from typing import Literal

    from renderlab import plugins
    from renderlab.contracts.config_types import Strict
    from renderlab.contracts.world import WorldKind
    from renderlab.errors import UserError
    from renderlab.scenario import load_scenario
    from renderlab.scenario.kinds import CAMERA_PATHS, FILE_TRAJECTORIES

    class Rock(Strict):
        kind: Literal["rock"] = "rock"

    def rock_plan(scenario, base_dir):
        from renderlab.photometry import make_law
        from renderlab.render.scene import BodySpec, SceneDescription
        from renderlab.worlds.base import WorldPlan, frame_specs

        body = BodySpec(name="rock", body_id=0, shape="sphere", center_m=np.zeros(3), R_render_from_body=np.eye(3),
                        law=make_law("lambert"), albedo=0.2, radius_m=150.0)
        return WorldPlan(frames=frame_specs(scenario, base_dir), render_frame={"name": "ROCK_FIXED"},
                         static_scene=SceneDescription(bodies=[body], render_frame={"name": "ROCK_FIXED"}))

    pos, vel, rots = ev5_truth(T_SAMPLES)
    quat = write_csv(tmp_path / "traj.csv", pos, vel, rots)
    text = (f'[world]\nkind = "rock"\n{CAMERA.format(f=30.0)}[render]\nspp = 1\nnear_clip_m = 1.0\n'
            f'[trajectory]\nkind = "table"\nfile = "traj.csv"\n{quat}times_s = {T_FRAMES}\n')
    plugins.worlds.register("rock", WorldKind("rock", Rock, {**CAMERA_PATHS, **FILE_TRAJECTORIES}, rock_plan))
    try:
        frames, chans = render(tmp_path, text)
        for k, (rec, ch) in enumerate(zip(frames, chans)):
            i = int(np.flatnonzero(T_SAMPLES == T_FRAMES[k])[0])
            assert np.abs(np.array(rec["pose"]["position_m"]) - pos[i]).max() < 1e-6
            assert reprojection_px(ch, rots[i], pos[i], rec) < 1e-3
    finally:
        plugins.worlds.unregister("rock")
    plugins.worlds.register("rock", WorldKind("rock", Rock, dict(CAMERA_PATHS), rock_plan))
    try:
        (tmp_path / "sc.toml").write_text(text)
        with pytest.raises(UserError, match="trajectory.kind 'table' does not fit world.kind 'rock'"):
            load_scenario(tmp_path / "sc.toml")
    finally:
        plugins.worlds.unregister("rock")

