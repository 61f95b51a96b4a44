"""``renderlab export`` keeps the frame and object names a set was made in, and epochs round-trip exactly.

Before: a set rendered from SPICE kernels in J2000 about the Moon was exported with ``REF_FRAME = SCENE``,
``CENTER_NAME = ORIGIN``, ``OBJECT_NAME = CAMERA``; an Earth set wrote its per-frame ENU tile positions as one
trajectory in ``ENU_TILE``. Oracles: spiceypy (``str2et`` of the exported epoch text, ``spkpos`` there) for the
SPICE set; the circular orbit's radius and speed (two-body, from its elements) for the Earth set."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from renderlab.cli import main
from renderlab.trajectory_io import read_aem, read_oem

sp = pytest.importorskip("spiceypy")

REPO = Path(__file__).resolve().parents[1]
SC, EPOCH = -998, "2030-01-01T00:00:00"
FK = f"KPL/FK\n\\begindata\nNAIF_BODY_NAME += ( 'RL_LUNAR_PROBE' )\nNAIF_BODY_CODE += ( {SC} )\n\\begintext\n"
LSK = ("KPL/LSK\n\\begindata\nDELTET/DELTA_T_A = 32.184\nDELTET/K = 1.657D-3\nDELTET/EB = 1.671D-2\n"
       "DELTET/M = ( 6.239996D0 1.99096871D-7 )\nDELTET/DELTA_AT = ( 37, @2017-JAN-1 )\n\\begintext\n")


def _kernels(d: Path) -> None:
    """FK naming the probe, and a type-13 SPK of it about the Moon (301) in J2000 (the LSK is only for writing)."""
    (d / "probe.tf").write_text(FK)
    (d / "w.tls").write_text(LSK)
    sp.furnsh(str(d / "w.tls"))
    try:
        ets = sp.str2et(EPOCH) + np.arange(0.0, 101.0, 10.0)
        t = ets - ets[0]
        st = np.stack([3.0e3 - 0.4 * t, 200.0 + 1.2 * t, 150.0 + 0 * t, -0.4 + 0 * t, 1.2 + 0 * t, 0 * t], 1)
        h = sp.spkopn(str(d / "probe.bsp"), "renderlab test", 0)
        sp.spkw13(h, SC, 301, "J2000", ets[0], ets[-1], "probe", 3, len(ets), st, ets)
        sp.spkcls(h)
    finally:
        sp.unload(str(d / "w.tls"))


SCENE = f"""[world]
kind = "analytic"
[[world.bodies]]
name = "moon"
shape = "sphere"
radius_m = 1737400.0
[camera]
width = 16
height = 12
fov_deg = 60.0
[render]
spp = 1
near_clip_m = 1000.0
far_clip_m = 1e8
[trajectory]
kind = "spice"
kernels = ["w.tls", "probe.tf", "probe.bsp"]
observer = "RL_LUNAR_PROBE"
center = "MOON"
frame = "J2000"
epoch_utc = "{EPOCH}Z"
times_s = [0.0, 30.0, 60.0]
attitude = "look_at"
"""


def test_a_spice_set_exports_in_its_frame_about_its_centre(tmp_path, capsys):
    """Fails before the change (REF_FRAME = SCENE, CENTER_NAME = ORIGIN, OBJECT_NAME = CAMERA)."""
    _kernels(tmp_path)
    (tmp_path / "moon.toml").write_text(SCENE)
    assert main(["render", str(tmp_path / "moon.toml"), "--out", str(tmp_path / "ts"), "--quiet"]) == 0
    oem, aem = tmp_path / "probe.oem", tmp_path / "probe.aem"
    assert main(["export", str(tmp_path / "ts"), "--oem", str(oem), "--aem", str(aem)]) == 0
    capsys.readouterr()
    head = {k.strip(): v.strip() for k, v in (ln.split("=", 1) for ln in oem.read_text().splitlines() if "=" in ln)}
    assert (head["REF_FRAME"], head["CENTER_NAME"], head["OBJECT_NAME"]) == ("J2000", "MOON", "RL_LUNAR_PROBE")
    a = read_aem(aem)
    assert a.frame == "J2000" and a.object_name == "RL_LUNAR_PROBE"
    stamps = [ln.split()[0] for ln in oem.read_text().splitlines() if ln.startswith("2030")]
    assert stamps == ["2030-01-01T00:00:00.000000000", "2030-01-01T00:00:30.000000000", "2030-01-01T00:01:00.000000000"]
    o = read_oem(oem)
    for n in (tmp_path / "w.tls", tmp_path / "probe.tf", tmp_path / "probe.bsp"):
        sp.furnsh(str(n))
    try:
        ref = np.array([sp.spkpos("RL_LUNAR_PROBE", sp.str2et(s), "J2000", "NONE", "MOON")[0] for s in stamps]) * 1e3
    finally:
        for n in (tmp_path / "w.tls", tmp_path / "probe.tf", tmp_path / "probe.bsp"):
            sp.unload(str(n))
    assert np.abs(o.positions_m - ref).max() < 1e-3
    # round trip: the exported OEM/AEM drive the same scene to the same poses
    back = SCENE.split("[trajectory]")[0] + ('[trajectory]\nkind = "ccsds"\noem = "probe.oem"\naem = "probe.aem"\n'
                                              'camera_frame = "CAMERA"\ntimes_s = [0.0, 30.0, 60.0]\n')
    (tmp_path / "back.toml").write_text(back)
    assert main(["render", str(tmp_path / "back.toml"), "--out", str(tmp_path / "ts2"), "--quiet"]) == 0
    f1 = json.loads((tmp_path / "ts" / "manifest.json").read_text())
    f2 = json.loads((tmp_path / "ts2" / "manifest.json").read_text())
    p1 = np.array([f["pose"]["position_m"] for f in f1["frames"]])
    p2 = np.array([f["pose"]["position_m"] for f in f2["frames"]])
    assert np.abs(p1 - p2).max() < 1e-3 and [f["epoch_utc"] for f in f2["frames"]] == [s[:26] + "Z" for s in stamps]
    assert f2["render_frame"]["source_frame"] == "J2000" and f2["render_frame"]["source_center"] == "MOON"


def test_an_earth_set_exports_gcrf_states_not_enu_tiles(tmp_path, capsys):
    """Fails before the change (the per-frame ENU-tile positions as one trajectory in ENU_TILE)."""
    out = tmp_path / "earth"
    assert main(["render", str(REPO / "scenes" / "earth_leo.toml"), "--out", str(out), "--frames", "2", "--set",
                 "camera.width=16", "--set", "camera.height=16", "--set", "render.spp=1", "--quiet"]) == 0
    oem = tmp_path / "leo.oem"
    assert main(["export", str(out), "--oem", str(oem)]) == 0
    capsys.readouterr()
    o = read_oem(oem)
    assert (o.frame, o.center_name) == ("GCRF", "EARTH")
    a = 6378137.0 + 1000e3  # earth_leo: circular, Kepler two-body (trajectory.j2 = false)
    assert np.abs(np.linalg.norm(o.positions_m, axis=1) - a).max() < 1e-3
    assert np.abs(np.linalg.norm(o.velocities_m_s, axis=1) - math.sqrt(3.986004418e14 / a)).max() < 1e-6
    assert [ln.split()[0] for ln in oem.read_text().splitlines() if ln.startswith("2024")] == [
        "2024-06-21T10:18:00.000000000", "2024-06-21T10:18:30.000000000"]
