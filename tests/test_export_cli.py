"""``renderlab export``: a rendered truth set's camera trajectory as CCSDS OEM/AEM, read back to the manifest's
poses (positions to 1 mm, attitude to 0.1″); bad requests are one line with nothing written."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from renderlab.cli import main

REPO = Path(__file__).resolve().parents[1]
TINY = ["--frames", "3", "--set", "camera.width=32", "--set", "camera.height=24", "--set", "camera.fx=37.5",
        "--set", "camera.fy=37.5", "--set", "camera.cx=15.5", "--set", "camera.cy=11.5", "--set", "render.spp=1",
        "--quiet"]


def test_export_round_trip(tmp_path, capsys):
    from renderlab.trajectory_io.ccsds import read_aem, read_oem

    ts = tmp_path / "ts"
    assert main(["render", str(REPO / "scenes" / "analytic_sphere_box.toml"), "--out", str(ts), *TINY]) == 0
    oem, aem = tmp_path / "cam.oem", tmp_path / "cam.aem"
    assert main(["export", str(ts), "--oem", str(oem), "--aem", str(aem), "--epoch-utc", "2026-12-02T00:00:00Z"]) == 0
    frames = json.loads((ts / "manifest.json").read_text())["frames"]
    pos = np.array([f["pose"]["position_m"] for f in frames])
    q = np.array([f["pose"]["quat_render_from_cam_xyzw"] for f in frames])
    o, a = read_oem(oem), read_aem(aem)
    assert np.abs(o.positions_m - pos).max() < 1e-3
    ang = (Rotation.from_quat(a.quat_xyzw) * Rotation.from_quat(q).inv()).magnitude()
    assert np.degrees(ang).max() * 3600 < 0.1
    capsys.readouterr()
    assert main(["export", str(ts), "--oem", str(oem)]) == 2 and "exists" in capsys.readouterr().err
    assert main(["export", str(ts)]) == 2 and "--oem" in capsys.readouterr().err
    assert main(["export", str(ts), "--oem", str(tmp_path / "no" / "x.oem")]) == 2
    assert not (tmp_path / "no").exists()
