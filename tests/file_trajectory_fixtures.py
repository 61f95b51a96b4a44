"""Shared pieces of ``tests/test_world_file_trajectories.py`` (test helper, not part of renderlab): each world's known
trajectory, the independent writers of its OEM (``oem`` package), SPK/CK (spiceypy) and CSV files, the render call and
the projection oracles (OpenCV, astropy). The module docstring of the test file says what is checked."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

sp = pytest.importorskip("spiceypy")

cv2 = pytest.importorskip("cv2")

OpenEXR = pytest.importorskip("OpenEXR")

from test_trajectory_sources import LSK, SCLK  # noqa: E402  (LSK with NAIF's leap seconds, SCLK of body -999)
from tiny_ev5 import TINY_EV5_WORLD  # noqa: E402

EPOCH0 = "2024-06-21T10:18:00"            # inside astropy's bundled IERS tables

T_SAMPLES = np.arange(7) * 2.0            # s after EPOCH0: the files' samples

T_FRAMES = [0.0, 8.0]                     # frames at samples: the files' own states

SC, CK_ID = -999, -999000

CAMERA = "[camera]\nwidth = 32\nheight = 32\nfx = {f}\nfy = {f}\ncx = 15.5\ncy = 15.5\n"

MU, RE = 3.986004418e14, 6378137.0

WGS_F = 1 / 298.257223563

WGS_E2 = WGS_F * (2 - WGS_F)



def look_at_R(p, q, up):
    """R_frame_from_cam of a camera at p looking at q (+z boresight, +x right, +y down, image top toward up)."""
    z = (q - p) / np.linalg.norm(q - p)
    y = -(up - (up @ z) * z)
    y /= np.linalg.norm(y)
    return np.column_stack([np.cross(y, z), y, z])



def iso(t: float) -> str:
    from datetime import datetime, timedelta

    return (datetime.fromisoformat(EPOCH0) + timedelta(seconds=float(t))).isoformat(timespec="microseconds")



# ---------------------------------------------------------------------- the three trajectories (truth)
def ev5_truth(t):
    """Camera in EV5_FIXED: an arc at 900 m, looking near the body centre (m, m/s, R_frame_from_cam)."""
    t = np.asarray(t, float)
    az, w, el = 0.3 + 0.002 * t, 0.002, np.radians(20)
    pos = 900 * np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.full_like(t, np.sin(el))], 1)
    vel = 900 * w * np.stack([-np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.zeros_like(t)], 1)
    return pos, vel, [look_at_R(p, EV5_AIM, np.array([0, 0, 1.0])) for p in pos]



def microsat_truth(t):
    """Camera relative to the target's centre of mass, chaser LVLH."""
    t = np.asarray(t, float)
    pos = np.stack([np.full_like(t, 0.1), 4.5 + 0.05 * t, 0.2 - 0.01 * t], 1)
    vel = np.tile([0.0, 0.05, -0.01], (len(t), 1))
    return pos, vel, [look_at_R(p, MICROSAT_AIM, np.array([1.0, 0, 0])) for p in pos]



def earth_truth(t):
    """GCRF: a circular 1000 km, 45° orbit over Portugal at the epoch; attitude nadir tilted 2° about camera x."""
    t = np.asarray(t, float)
    a, inc = RE + 1.0e6, np.radians(45.0)
    n = np.sqrt(MU / a**3)
    u = n * (t + 1080.0)
    P, Q = np.array([1.0, 0, 0]), np.array([0, np.cos(inc), np.sin(inc)])
    pos = a * (np.cos(u)[:, None] * P + np.sin(u)[:, None] * Q)
    vel = a * n * (-np.sin(u)[:, None] * P + np.cos(u)[:, None] * Q)
    tilt = Rotation.from_euler("x", 2.0, degrees=True).as_matrix()
    return pos, vel, [nadir_R(r, v) @ tilt for r, v in zip(pos, vel)]



def nadir_R(r, v):
    """Nadir camera: +z to the geocentre, image top along the velocity."""
    z = -r / np.linalg.norm(r)
    y = -(v - (v @ z) * z)
    y /= np.linalg.norm(y)
    return np.column_stack([np.cross(y, z), y, z])



EV5_AIM = np.array([30.0, -20.0, 10.0])

MICROSAT_AIM = np.array([0.2, 0.0, -0.1])

SUN0_EV5 = np.array([1.0, 0.2, 0.4])

Q0 = np.array([0.1, 0.3, -0.2, 0.9])



# ---------------------------------------------------------------------- writers
def write_oem(path, frame, center, pos, vel):
    from astropy.time import Time
    from oem import OrbitEphemerisMessage
    from oem.components import EphemerisSegment, HeaderSection, MetaDataSection

    stamps = [iso(t) for t in T_SAMPLES]
    meta = MetaDataSection({"OBJECT_NAME": "RL_CAMERA_SC", "OBJECT_ID": "2024-000A", "CENTER_NAME": center,
                            "REF_FRAME": frame, "TIME_SYSTEM": "UTC", "START_TIME": stamps[0],
                            "STOP_TIME": stamps[-1]}, version="2.0")
    cols = (tuple(Time(stamps, scale="utc")), *(tuple(c) for c in np.hstack([pos, vel]).T / 1e3))
    seg = EphemerisSegment(meta, cols, version="2.0")
    OrbitEphemerisMessage(HeaderSection({"CCSDS_OEM_VERS": "2.0", "CREATION_DATE": EPOCH0,
                                         "ORIGINATOR": "renderlab test"}), [seg]).save_as(str(path))



def write_spice(d: Path, frame, center, center_code, pos, vel, rots) -> list[str]:
    """LSK, SCLK, an FK (the world's frame as a TK alias of J2000, the camera's CK frame), SPK type 13, CK type 3."""
    fk = f"""KPL/FK
\\begindata
NAIF_BODY_NAME += ( 'RL_CAMERA_SC' )
NAIF_BODY_CODE += ( {SC} )
{"" if center_code == 399 else f"NAIF_BODY_NAME += ( '{center}' )" + chr(10) + f"NAIF_BODY_CODE += ( {center_code} )"}
FRAME_{frame} = 1499001
FRAME_1499001_NAME = '{frame}'
FRAME_1499001_CLASS = 4
FRAME_1499001_CLASS_ID = 1499001
FRAME_1499001_CENTER = {center_code}
TKFRAME_1499001_RELATIVE = 'J2000'
TKFRAME_1499001_SPEC = 'MATRIX'
TKFRAME_1499001_MATRIX = ( 1 0 0 0 1 0 0 0 1 )
FRAME_RL_CAM = {CK_ID}
FRAME_{CK_ID}_NAME = 'RL_CAM'
FRAME_{CK_ID}_CLASS = 3
FRAME_{CK_ID}_CLASS_ID = {CK_ID}
FRAME_{CK_ID}_CENTER = {SC}
CK_{CK_ID}_SCLK = {SC}
CK_{CK_ID}_SPK = {SC}
\\begintext
"""
    names = {"rl.tls": LSK, "rl.tsc": SCLK, "rl.tf": fk}
    for name, text in names.items():
        (d / name).write_text(text)
    for name in names:
        sp.furnsh(str(d / name))
    try:
        ets = sp.str2et(EPOCH0) + T_SAMPLES
        h = sp.spkopn(str(d / "rl.bsp"), "renderlab test", 0)
        sp.spkw13(h, SC, center_code, "J2000", ets[0], ets[-1], "arc", 3, len(ets), np.hstack([pos, vel]) / 1e3, ets)
        sp.spkcls(h)
        ticks = np.array([sp.sce2c(SC, et) for et in ets])
        quats = np.array([sp.m2q(np.ascontiguousarray(R.T)) for R in rots])  # C-matrix: J2000 → camera
        h = sp.ckopn(str(d / "rl.bc"), "renderlab test", 0)
        sp.ckw03(h, ticks[0], ticks[-1], CK_ID, "J2000", False, "arc", len(ticks), ticks, quats,
                 np.zeros((len(ticks), 3)), 1, ticks[:1])
        sp.ckcls(h)
    finally:
        for name in names:
            sp.unload(str(d / name))
    return [*names, "rl.bsp", "rl.bc"]



def write_csv(path, pos, vel, rots, wxyz_frame_to_cam=False):
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        order = ["qw", "qx", "qy", "qz"] if wxyz_frame_to_cam else ["qx", "qy", "qz", "qw"]
        w.writerow(["epoch", "x_m", "y_m", "z_m", "vx_m_s", "vy_m_s", "vz_m_s", *order])
        for t, p, v, R in zip(T_SAMPLES, pos, vel, rots):
            q = Rotation.from_matrix(R.T if wxyz_frame_to_cam else R).as_quat()
            q = q[[3, 0, 1, 2]] if wxyz_frame_to_cam else q
            w.writerow([iso(t) + "Z", *map(repr, p), *map(repr, v), *map(repr, q)])
    if wxyz_frame_to_cam:
        return 'quaternion_order = "wxyz"\nquaternion_direction = "frame_to_cam"\n'
    return 'quaternion_order = "xyzw"\nquaternion_direction = "cam_to_frame"\n'



def trajectory_block(kind: str, d: Path, frame: str, center: str, center_code: int, truth, aim=None, up=None) -> str:
    """Write the files of one source into ``d`` and return its ``[trajectory]`` section."""
    pos, vel, rots = truth(T_SAMPLES)
    times = f"times_s = {T_FRAMES}\n"
    if kind == "ccsds":
        pytest.importorskip("oem")
        write_oem(d / "traj.oem", frame, center, pos, vel)
        look = "" if aim is None else f'attitude = "look_at"\ntarget_m = {list(aim)}\nup = {list(up)}\n'
        return f'[trajectory]\nkind = "ccsds"\noem = "traj.oem"\n{look}{times}'
    if kind == "spice":
        kernels = write_spice(d, frame, center, center_code, pos, vel, rots)
        return (f'[trajectory]\nkind = "spice"\nkernels = {json.dumps(kernels)}\nobserver = "RL_CAMERA_SC"\n'
                f'center = "{center}"\nframe = "{frame}"\ncamera_frame = "RL_CAM"\nepoch_utc = "{EPOCH0}Z"\n{times}')
    return f'[trajectory]\nkind = "table"\nfile = "traj.csv"\nframe = "{frame}"\n{times}'



def render(d: Path, text: str):
    from renderlab.pipeline import render_truthset
    from renderlab.scenario import load_scenario

    (d / "sc.toml").write_text(text)
    sc, base = load_scenario(d / "sc.toml")
    out = render_truthset(sc, base, d / "set", progress=False)
    frames = json.loads((out / "manifest.json").read_text())["frames"]
    chans = []
    for rec in frames:
        with OpenEXR.File(str(out / rec["exr"]), separate_channels=True) as exr:
            ch = {k: np.asarray(v.pixels, np.float64) for k, v in exr.channels().items()}
        ch["id"] = np.asarray(ch["id"], np.uint32).view(np.int32)  # stored as uint32: 2³² − 1 = no hit = −1
        chans.append(ch)
    return frames, chans



# ---------------------------------------------------------------------- oracles
def rot_angle(a, b) -> float:
    return float((Rotation.from_matrix(a).inv() * Rotation.from_matrix(b)).magnitude())



def quat_R(q) -> np.ndarray:
    return Rotation.from_quat(q).as_matrix()



def project(points, R_frame_from_cam, cam_pos, rec) -> np.ndarray:
    """Pixel (s, l) of frame points by cv2.projectPoints of the pose (pinhole intrinsics of the manifest)."""
    c = rec["camera"]
    K = np.array([[c["fx"], 0, c["cx"]], [0, c["fy"], c["cy"]], [0, 0, 1.0]])
    R = R_frame_from_cam.T
    rvec, _ = cv2.Rodrigues(R)
    uv, _ = cv2.projectPoints(np.asarray(points, np.float64).reshape(-1, 1, 3), rvec, -R @ cam_pos, K, None)
    return uv.reshape(-1, 2)



def reprojection_px(ch, R_frame_from_cam, cam_pos, rec, to_frame=lambda P: P) -> float:
    """Largest distance from a hit pixel's centre to where cv2 projects its position AOV (in the pose's frame)."""
    hit = ch["id"] >= 0
    assert hit.sum() >= 20, "the body is in view"
    P = to_frame(np.stack([ch["P.X"], ch["P.Y"], ch["P.Z"]], -1)[hit])
    uv = project(P, R_frame_from_cam, cam_pos, rec)
    L, S = np.nonzero(hit)
    return float(np.abs(uv - np.stack([S, L], 1)).max())



def assert_epochs(frames):
    assert [f["time_s"] for f in frames] == T_FRAMES
    assert [f["epoch_utc"] for f in frames] == [iso(t) + "Z" for t in T_FRAMES]



SOURCES = ["ccsds", "spice", "table"]



# ---------------------------------------------------------------------- Earth
def gcrs_to_itrs(r, v, stamps):
    """(r, v) GCRF → ITRS by astropy, and the rotation matrices M (r_itrs = M r_gcrs) from transformed axes."""
    import astropy.units as u
    from astropy.coordinates import GCRS, ITRS, CartesianDifferential, CartesianRepresentation
    from astropy.time import Time

    times = Time(stamps, scale="utc")
    rep = CartesianRepresentation(r.T * u.m, differentials=CartesianDifferential(v.T * u.m / u.s))
    itrs = GCRS(rep, obstime=times).transform_to(ITRS(obstime=times))
    r_i = itrs.cartesian.xyz.to_value(u.m).T
    v_i = itrs.velocity.d_xyz.to_value(u.m / u.s).T
    M = np.empty((len(stamps), 3, 3))
    for j, e in enumerate(np.eye(3) * 7e6):
        axis = GCRS(CartesianRepresentation(np.tile(e, (len(stamps), 1)).T * u.m), obstime=times)
        M[:, :, j] = axis.transform_to(ITRS(obstime=times)).cartesian.xyz.to_value(u.m).T / 7e6
    return r_i, v_i, M



def geodetic_ssp(r_ecef):
    """The WGS-84 point under the spacecraft along the ellipsoid normal (fixed-point latitude iteration)."""
    x, y, z = r_ecef
    p = np.hypot(x, y)
    lat = np.arctan2(z, p)
    for _ in range(20):
        N = RE / np.sqrt(1 - WGS_E2 * np.sin(lat) ** 2)
        lat = np.arctan2(z + WGS_E2 * N * np.sin(lat), p)
    lon = np.arctan2(y, x)
    N = RE / np.sqrt(1 - WGS_E2 * np.sin(lat) ** 2)
    return np.array([N * np.cos(lat) * np.cos(lon), N * np.cos(lat) * np.sin(lon), N * (1 - WGS_E2) * np.sin(lat)])



def bilinear(img, s, ln):
    s0, l0 = int(np.floor(s)), int(np.floor(ln))
    a, b = s - s0, ln - l0
    return ((1 - a) * (1 - b) * img[l0, s0] + a * (1 - b) * img[l0, s0 + 1] + (1 - a) * b * img[l0 + 1, s0]
            + a * b * img[l0 + 1, s0 + 1])



# ---------------------------------------------------------------------- bad input
CSV_REL = "time_s,x_m,y_m,z_m\n0,7378137,0,0\n10,7378137,75000,0\n"

BAD = {  # world section, [trajectory] section, files to write (name → text or an OEM frame), the line's text
    "ev5 frame": (TINY_EV5_WORLD, '[trajectory]\nkind = "ccsds"\noem = "t.oem"\nattitude = "look_at"\n', "J2000",
                  "the OEM's REF_FRAME 'J2000' is not a frame world.kind 'ev5' can use ('EV5_FIXED')"),
    "microsat no attitude": ('[world]\nkind = "microsat"\n', '[trajectory]\nkind = "table"\nfile = "t.csv"\n'
                             'frame = "LVLH"\n', None, "kind 'table' needs 'quaternion_order' and "
                             "'quaternion_direction' (or attitude = \"look_at\"); world.kind 'microsat' has no "
                             "default pointing"),
    "microsat table frame": ('[world]\nkind = "microsat"\n', '[trajectory]\nkind = "table"\nfile = "t.csv"\n'
                             'attitude = "look_at"\n', None, "trajectory.frame: world.kind 'microsat' needs the "
                             "table's frame ('LVLH')"),
    "earth no epochs": ('[world]\nkind = "earth"\n', '[trajectory]\nkind = "table"\nfile = "t.csv"\nframe = "GCRF"\n',
                        None, "world.kind 'earth' needs epochs"),
    "earth eme2000": ('[world]\nkind = "earth"\n', '[trajectory]\nkind = "ccsds"\noem = "t.oem"\n', "EME2000",
                      "frame 'EME2000' is not GCRF"),
}

