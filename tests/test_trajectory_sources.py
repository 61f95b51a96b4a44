"""Own trajectories: a table, CCSDS OEM/AEM and SPICE kernels of one camera trajectory give the same frame poses.

The test writes every file itself: a Parquet table (pyarrow), an OEM and an AEM (renderlab's writer), and SPICE
kernels (spiceypy: a type-13 SPK, a type-3 CK, and hand-written LSK, SCLK and FK text kernels). Each is loaded
through :func:`renderlab.scenario.load_scenario` and :func:`renderlab.worlds.base.frame_specs` (what the pipeline
uses): at the samples and between them the three agree to ≤ 1 mm and ≤ 0.1″. One tiny frame is rendered from the
table through ``renderlab render``; bad files exit 2 with one line and no output folder.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

sp = pytest.importorskip("spiceypy")

from renderlab.cli import main  # noqa: E402
from renderlab.errors import UserError  # noqa: E402
from renderlab.geometry.rotations import look_at  # noqa: E402
from renderlab.scenario import load_scenario  # noqa: E402
from renderlab.trajectory_io import (  # noqa: E402
    PoseSeries,
    export_truthset,
    parse_epoch,
    read_aem,
    read_oem,
    write_aem,
    write_oem,
)
from renderlab.worlds.base import frame_specs  # noqa: E402

EPOCH0 = "2030-01-01T00:00:00Z"
T_SAMPLES = np.array([0.0, 2.0, 4.0, 6.0, 8.0])
OBS, CENTER, CK_FRAME, SC, CK_ID = "RL_CAMERA_SC", "RL_ORIGIN", "RL_CAM", -999, -999000
ARCSEC = np.radians(1 / 3600)
MONTHS = "JAN FEB MAR APR MAY JUN JUL AUG SEP OCT NOV DEC".split()
LEAPS = [(1972, 1, 10), (1972, 7, 11)] + [(y, 1, n) for y, n in zip(range(1973, 1981), range(12, 20))] + [
    (1981, 7, 20), (1982, 7, 21), (1983, 7, 22), (1985, 7, 23), (1988, 1, 24), (1990, 1, 25), (1991, 1, 26),
    (1992, 7, 27), (1993, 7, 28), (1994, 7, 29), (1996, 1, 30), (1997, 7, 31), (1999, 1, 32), (2006, 1, 33),
    (2009, 1, 34), (2012, 7, 35), (2015, 7, 36), (2017, 1, 37)]
LSK = ("KPL/LSK\n\\begindata\nDELTET/DELTA_T_A = 32.184\nDELTET/K = 1.657D-3\nDELTET/EB = 1.671D-2\n"
       "DELTET/M = ( 6.239996D0 1.99096871D-7 )\nDELTET/DELTA_AT = ( "
       + "\n  ".join(f"{n}, @{y}-{MONTHS[m - 1]}-1" for y, m, n in LEAPS) + " )\n\\begintext\n")
SCLK = f"""KPL/SCLK
\\begindata
SCLK_KERNEL_ID = ( @2000-01-01/00:00:00 )
SCLK_DATA_TYPE_{-SC} = ( 1 )
SCLK01_TIME_SYSTEM_{-SC} = ( 1 )
SCLK01_N_FIELDS_{-SC} = ( 2 )
SCLK01_MODULI_{-SC} = ( 4294967296 65536 )
SCLK01_OFFSETS_{-SC} = ( 0 0 )
SCLK01_OUTPUT_DELIM_{-SC} = ( 1 )
SCLK_PARTITION_START_{-SC} = ( 0.0 )
SCLK_PARTITION_END_{-SC} = ( 2.8147497671065E+14 )
SCLK01_COEFFICIENTS_{-SC} = ( 0.0 0.0 1.0 )
\\begintext
"""
FK = f"""KPL/FK
\\begindata
NAIF_BODY_NAME += ( '{OBS}' )
NAIF_BODY_CODE += ( {SC} )
NAIF_BODY_NAME += ( '{CENTER}' )
NAIF_BODY_CODE += ( -998 )
FRAME_{CK_FRAME} = {CK_ID}
FRAME_{CK_ID}_NAME = '{CK_FRAME}'
FRAME_{CK_ID}_CLASS = 3
FRAME_{CK_ID}_CLASS_ID = {CK_ID}
FRAME_{CK_ID}_CENTER = {SC}
CK_{CK_ID}_SCLK = {SC}
CK_{CK_ID}_SPK = {SC}
FRAME_RL_CAM2 = -999001
FRAME_-999001_NAME = 'RL_CAM2'
FRAME_-999001_CLASS = 3
FRAME_-999001_CLASS_ID = -999001
FRAME_-999001_CENTER = {SC}
CK_-999001_SCLK = {SC}
CK_-999001_SPK = {SC}
\\begintext
"""
SCENE = """name = "own_trajectory"
[world]
kind = "analytic"
[[world.bodies]]
name = "ground"
shape = "plane"
size_m = [12.0, 12.0]
[[world.bodies]]
name = "sphere"
shape = "sphere"
center_m = [-1.2, 0.6, 1.0]
radius_m = 1.0
albedo = 0.5
[camera]
width = 32
height = 24
fx = 30.0
fy = 30.0
cx = 16.0
cy = 12.0
[render]
spp = 1
near_clip_m = 0.01
far_clip_m = 1000.0
[trajectory]
"""


def truth(t):
    """The camera trajectory: a slow arc around the sphere (positions m, velocities m/s, R_frame_from_cam)."""
    t = np.asarray(t, float)
    az = np.radians(-100.0 + 3.0 * t)
    pos = np.stack([9 * np.cos(az), 9 * np.sin(az), 5.0 + 0.1 * t], 1)
    w = np.radians(3.0)
    vel = np.stack([-9 * w * np.sin(az), 9 * w * np.cos(az), np.full_like(t, 0.1)], 1)
    rots = Rotation.from_quat([look_at(p, [-1.2, 0.6, 1.0 + 0.05 * tk], [0, 0, 1]).as_quat() for p, tk in zip(pos, t)])
    return pos, vel, rots


def write_kernels(d: Path) -> list[str]:
    """LSK, SCLK, FK text kernels and a type-13 SPK and type-3 CK of :func:`truth` at the samples."""
    for name, text in (("rl.tls", LSK), ("rl.tsc", SCLK), ("rl.tf", FK)):
        (d / name).write_text(text)
    pos, vel, rots = truth(T_SAMPLES)
    names = [str(d / n) for n in ("rl.tls", "rl.tsc", "rl.tf")]
    for n in names:
        sp.furnsh(n)
    try:
        ets = sp.str2et(EPOCH0.rstrip("Z")) + T_SAMPLES
        h = sp.spkopn(str(d / "rl.bsp"), "renderlab test", 0)
        sp.spkw13(h, SC, -998, "J2000", ets[0], ets[-1], "arc", 3, len(ets), np.hstack([pos, vel]) / 1e3, ets)
        sp.spkcls(h)
        ticks = np.array([sp.sce2c(SC, et) for et in ets])
        quats = np.array([sp.m2q(np.ascontiguousarray(m.T)) for m in rots.as_matrix()])  # SPICE C-matrix: frame → camera
        h = sp.ckopn(str(d / "rl.bc"), "renderlab test", 0)
        sp.ckw03(h, ticks[0], ticks[-1], CK_ID, "J2000", False, "arc", len(ticks), ticks, quats,
                 np.zeros((len(ticks), 3)), 1, ticks[:1])
        sp.ckcls(h)
    finally:
        for n in names:
            sp.unload(n)
    return ["rl.tls", "rl.tsc", "rl.tf", "rl.bsp", "rl.bc"]


def write_sources(d: Path) -> dict[str, str]:
    """The three sources of :func:`truth` and a scenario TOML per source → {source: scenario path}."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    pos, vel, rots = truth(T_SAMPLES)
    e0 = parse_epoch(EPOCH0)
    q = rots.inv().as_quat()  # written frame_to_cam, scalar first
    cols = {"epoch": [e0.plus(t).iso("UTC", 6) for t in T_SAMPLES], "x_m": pos[:, 0], "y_m": pos[:, 1],
            "z_m": pos[:, 2], "vx_m_s": vel[:, 0], "vy_m_s": vel[:, 1], "vz_m_s": vel[:, 2],
            "qw": q[:, 3], "qx": q[:, 0], "qy": q[:, 1], "qz": q[:, 2]}
    pq.write_table(pa.table(cols), d / "poses.parquet")
    series = PoseSeries(T_SAMPLES, pos, rots.as_quat(), "J2000", e0, vel, object_name=OBS, center_name=CENTER,
                        attitude_frame=CK_FRAME)
    write_oem(d / "traj.oem", series, creation_date="2030-01-01T00:00:00")
    write_aem(d / "att.aem", series, attitude_dir="B2A", quaternion_type="FIRST", creation_date="2030-01-01T00:00:00")
    kernels = write_kernels(d)
    times = "times_s = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0]\n"
    blocks = {
        "table": 'kind = "table"\nfile = "poses.parquet"\nquaternion_order = "wxyz"\n'
                 'quaternion_direction = "frame_to_cam"\nframe = "J2000"\n',
        "ccsds": f'kind = "ccsds"\noem = "traj.oem"\naem = "att.aem"\nobserver = "{OBS}"\ncenter = "{CENTER}"\n',
        "spice": f'kind = "spice"\nkernels = {json.dumps(kernels)}\nobserver = "{OBS}"\ncenter = "{CENTER}"\n'
                 f'frame = "J2000"\ncamera_frame = "{CK_FRAME}"\nepoch_utc = "{EPOCH0}"\n',
    }
    out = {}
    for name, block in blocks.items():
        (d / f"{name}.toml").write_text(SCENE + block + times)
        out[name] = str(d / f"{name}.toml")
    return out


@pytest.fixture(scope="module")
def sources(tmp_path_factory):
    d = tmp_path_factory.mktemp("own_traj")
    return d, write_sources(d)


def poses(path: str):
    sc, base = load_scenario(path)
    specs = frame_specs(sc, base)
    return np.array([s.pose.position_m for s in specs]), Rotation.from_quat([s.pose.rotation.as_quat() for s in specs])


def test_three_sources_give_the_same_frame_poses(sources):
    _, paths = sources
    got = {name: poses(p) for name, p in paths.items()}
    pos_t, _, rot_t = truth(T_SAMPLES)
    for name, (pos, rot) in got.items():
        assert len(pos) == 9
        assert np.abs(pos[::2] - pos_t).max() < 1e-6, name  # at the samples: the samples
        assert (rot[::2].inv() * rot_t).magnitude().max() < 1e-3 * ARCSEC, name
    ref_pos, ref_rot = got["spice"]
    for name in ("table", "ccsds"):
        pos, rot = got[name]
        assert np.abs(pos - ref_pos).max() < 1e-3, name  # ≤ 1 mm, between the samples too
        assert (rot.inv() * ref_rot).magnitude().max() < 0.1 * ARCSEC, name
    print("max |Δp| vs SPICE (m):", {n: float(np.abs(got[n][0] - ref_pos).max()) for n in ("table", "ccsds")},
          "max Δθ (arcsec):", {n: float((got[n][1].inv() * ref_rot).magnitude().max() / ARCSEC)
                               for n in ("table", "ccsds")})


def test_frames_carry_epochs_and_relative_times(sources):
    _, paths = sources
    sc, base = load_scenario(paths["ccsds"])
    specs = frame_specs(sc, base)
    assert [s.pose.time_s for s in specs] == list(range(9))
    assert specs[0].pose.epoch_utc == "2030-01-01T00:00:00.000000Z"
    assert specs[8].pose.epoch_utc == "2030-01-01T00:00:08.000000Z"


def test_ccsds_writer_round_trip(sources):
    d, _ = sources
    oem, aem = read_oem(d / "traj.oem"), read_aem(d / "att.aem", frame="J2000")
    pos, vel, rots = truth(T_SAMPLES)
    assert np.abs(oem.positions_m - pos).max() < 1e-9 and np.abs(oem.velocities_m_s - vel).max() < 1e-12
    assert (Rotation.from_quat(aem.quat_xyzw).inv() * rots).magnitude().max() < 1e-12
    assert oem.frame == "J2000" and aem.attitude_frame == CK_FRAME and oem.epoch0 == parse_epoch(EPOCH0)
    text = (d / "att.aem").read_text()
    assert "QUATERNION_TYPE" in text and "DATA_START" in text and "ATTITUDE_DIR" in text


def test_render_from_a_table_puts_its_poses_in_the_manifest(tmp_path):
    pos, _, rots = truth(T_SAMPLES)
    rows = ["time_s,x_m,y_m,z_m,qx,qy,qz,qw"] + [",".join(map(repr, [t, *p, *q])) for t, p, q in
                                                   zip(T_SAMPLES, pos, rots.as_quat())]
    (tmp_path / "poses.csv").write_text("\n".join(rows) + "\n")
    block = 'kind = "table"\nfile = "poses.csv"\nquaternion_order = "xyzw"\nquaternion_direction = "cam_to_frame"\n'
    (tmp_path / "sc.toml").write_text(SCENE + block + "times_s = [2.0, 6.0]\n")
    assert main(["render", str(tmp_path / "sc.toml"), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    frames = json.loads((tmp_path / "out" / "manifest.json").read_text())["frames"]
    assert [f["time_s"] for f in frames] == [2.0, 6.0]
    for f, k in zip(frames, (1, 3)):
        assert np.abs(np.array(f["pose"]["position_m"]) - pos[k]).max() < 1e-9
        assert (Rotation.from_quat(f["pose"]["quat_render_from_cam_xyzw"]).inv() * rots[k]).magnitude() < 1e-9
    with pytest.raises(UserError, match="give epoch_utc"):
        export_truthset(tmp_path / "out", oem=tmp_path / "x.oem")
    export_truthset(tmp_path / "out", oem=tmp_path / "x.oem", aem=tmp_path / "x.aem", epoch_utc=EPOCH0)
    oem, aem = read_oem(tmp_path / "x.oem"), read_aem(tmp_path / "x.aem")
    assert abs(oem.epoch0.minus(parse_epoch(EPOCH0).plus(2.0))) < 1e-9 and np.allclose(oem.times_s, [0, 4], atol=1e-9)
    assert np.abs(oem.positions_m - pos[[1, 3]]).max() < 1e-9 and oem.frame == aem.frame == "SCENE"
    assert (Rotation.from_quat(aem.quat_xyzw).inv() * rots[[1, 3]]).magnitude().max() < 1e-9


def test_look_at_attitude_and_camera_mount(sources):
    d, paths = sources
    text = Path(paths["ccsds"]).read_text().replace('aem = "att.aem"\n', 'attitude = "look_at"\ntarget_m = [0, 0, 1]\n')
    (d / "look.toml").write_text(text)
    pos, rot = poses(str(d / "look.toml"))
    assert (rot[4].inv() * look_at(pos[4], [0, 0, 1], [0, 0, 1])).magnitude() < 1e-12
    mount = Rotation.from_euler("z", 90, degrees=True)
    text = Path(paths["table"]).read_text() + f"camera_mount_quat_xyzw = {list(mount.as_quat())}\n"
    (d / "mount.toml").write_text(text)
    _, rot_m = poses(str(d / "mount.toml"))
    _, _, rots = truth(T_SAMPLES)
    assert (rot_m[::2].inv() * rots * mount).magnitude().max() < 1e-9


def test_ev5_frames_carry_epoch_utc():
    import copy

    from tiny_ev5 import TINY_WORLD

    from renderlab.scenario import scenario_from_dict
    from renderlab.worlds.base import make_plan

    sc = scenario_from_dict({"world": copy.deepcopy(TINY_WORLD), "camera": {"width": 16, "height": 12, "fx": 20.0,
                             "fy": 20.0, "cx": 8.0, "cy": 6.0},
                             "trajectory": {"kind": "ev5_descent", "frames": 2, "epoch_utc": EPOCH0}})
    plan = make_plan(sc, ".")
    stamps = [plan.frame_meta(f, plan.static_scene)["epoch_utc"] for f in plan.frames]
    assert stamps[0] == "2030-01-01T00:00:00.000000Z"
    assert abs(parse_epoch(stamps[1]).minus(parse_epoch(EPOCH0)) - plan.frames[1].pose.time_s) < 1e-6
    with pytest.raises(UserError, match="trajectory.epoch_utc"):
        scenario_from_dict({"world": copy.deepcopy(TINY_WORLD), "trajectory": {"kind": "ev5_descent",
                                                                               "epoch_utc": "tomorrow"}})


CSV_OK = "time_s,x_m,y_m,z_m,qx,qy,qz,qw\n0,0,-8,4,0,0,0,1\n1,0.1,-8,4,0,0,0,1\n2,0.2,-8,4,0,0,0,1\n"
TABLE = 'kind = "table"\nfile = "p.csv"\nquaternion_order = "xyzw"\nquaternion_direction = "cam_to_frame"\n'
BAD = {
    "missing column": (CSV_OK.replace(",z_m", "").replace(",4,", ","), TABLE, "missing column(s) z_m"),
    "time not increasing": (CSV_OK.replace("\n2,", "\n0.5,"), TABLE, "time does not increase at row 3"),
    "quaternion order": (CSV_OK.replace("qx,qy,qz,qw", "qw,qx,qy,qz"), TABLE, "quaternion columns stand in the order"),
    "quaternion order value": (CSV_OK, TABLE.replace('"xyzw"', '"xzyw"'), "quaternion_order"),
    "not a unit quaternion": (CSV_OK.replace("0,0,0,1\n1", "0,0,0,2\n1"), TABLE, "norm 2"),
    "table coverage": (CSV_OK, TABLE + "times_s = [1.0, 3.0]\n", "trajectory: frame 1 at 3 s is outside p.csv's coverage 0 s – 2 s"),
}


def _run_bad(tmp_path, capsys, scene_text):
    (tmp_path / "bad.toml").write_text(scene_text)
    rc = main(["render", str(tmp_path / "bad.toml"), "--out", str(tmp_path / "out"), "--quiet"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and err.count("\n") == 0 and err.startswith("renderlab: error: "), err
    assert not (tmp_path / "out").exists() and not list(tmp_path.glob(".out*"))
    return err


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_tables_exit_2_with_one_line(tmp_path, capsys, case):
    csv, block, needle = BAD[case]
    (tmp_path / "p.csv").write_text(csv)
    assert needle in _run_bad(tmp_path, capsys, SCENE + block)


@pytest.mark.parametrize("case,edit,needle", [
    ("outside coverage", ("times_s = [0.0", "times_s = [-1.0"), "frame 0 at 2029-12-31T23:59:59.000Z is outside the SPK"),
    ("past coverage", ("8.0]", "9.5]"), "SPK coverage of 'RL_CAMERA_SC': 2030-01-01T00:00:00.000Z – 2030-01-01T00:00:08"),
    ("no attitude", (f'camera_frame = "{CK_FRAME}"', 'camera_frame = "RL_CAM2"'), "outside the CK coverage of 'RL_CAM2'"),
    ("unknown frame", ('frame = "J2000"', 'frame = "NOT_A_FRAME"'), "trajectory.frame: unknown SPICE frame 'NOT_A"),
    ("unknown camera frame", (f'camera_frame = "{CK_FRAME}"', 'camera_frame = "NOPE"'), "unknown SPICE frame 'NOPE'"),
    ("unknown body", (f'observer = "{OBS}"', 'observer = "NOBODY"'), "unknown SPICE body 'NOBODY'"),
    ("missing kernel", ('"rl.bc"', '"gone.bc"'), "trajectory.kernels.4: file not found: gone.bc"),
    ("ccsds frame", None, "is not traj.oem's REF_FRAME"),
])
def test_bad_kernels_and_frames_exit_2_with_one_line(sources, tmp_path, capsys, case, edit, needle):
    d, paths = sources
    if edit is None:
        text = Path(paths["ccsds"]).read_text().replace('kind = "ccsds"', 'kind = "ccsds"\nframe = "IAU_MARS"')
    else:
        text = Path(paths["spice"]).read_text()
        assert text.count(edit[0]) == 1
        text = text.replace(*edit)
    for name in ("rl.tls", "rl.tsc", "rl.tf", "rl.bsp", "rl.bc", "traj.oem", "att.aem"):
        (tmp_path / name).write_bytes((d / name).read_bytes())
    assert needle in _run_bad(tmp_path, capsys, text)


def test_epochs_match_spice_str2et(tmp_path):
    (tmp_path / "rl.tls").write_text(LSK)
    sp.furnsh(str(tmp_path / "rl.tls"))
    try:
        for text in ("2030-01-01T00:00:00", "1999-12-31T23:59:59.999", "2016-12-31T23:59:60.5", "2024-07-18T13:14:15.25"):
            assert abs(parse_epoch(text).et - sp.str2et(text)) < 1e-6, text
        for text in ("2030-01-01 00:00:00 TDB", "2030-01-01 00:00:00 TDT"):
            assert abs(parse_epoch(text[:19], text[20:].replace("TDT", "TT")).et - sp.str2et(text)) < 1e-6
    finally:
        sp.unload(str(tmp_path / "rl.tls"))
    with pytest.raises(UserError, match="not an ISO epoch"):
        parse_epoch("Jan 1 2030")


def test_kvn_reader_skips_comments_and_joins_segments(sources, tmp_path):
    d, _ = sources
    text = (d / "traj.oem").read_text()
    head, rest = text.split("META_START", 1)
    meta, data = rest.split("META_STOP", 1)
    lines = [ln for ln in data.strip().splitlines()]
    two = (head + "COMMENT two segments\nMETA_START" + meta + "META_STOP\n" + "\n".join(lines[:3])
           + "\n\nMETA_START" + meta + "META_STOP\nCOMMENT boundary repeated\n" + "\n".join(lines[2:]) + "\n")
    (tmp_path / "two.oem").write_text(two)
    s = read_oem(tmp_path / "two.oem")
    assert np.allclose(s.times_s, T_SAMPLES) and s.labels[3].startswith("line ")
    (tmp_path / "bad.oem").write_text(two.replace("REF_FRAME", "REF_FRAMEX", 1))
    with pytest.raises(UserError, match="has no REF_FRAME"):
        read_oem(tmp_path / "bad.oem")
