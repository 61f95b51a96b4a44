"""The Earth world's camera comes from the ``[camera]`` section alone: ``trajectory.fov_deg`` (the older spelling) is
moved into it, refused when the camera says otherwise, and no longer overrides ``camera.fx`` with a 30° default.

Oracle: OpenCV's pinhole projection (``cv2.projectPoints``) with the camera matrix written from the scenario's own
numbers, and the field-of-view relation fx = (W/2)/tan(fov/2) evaluated here."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from renderlab.cli import main
from renderlab.errors import UserError
from renderlab.scenario import load_scenario, scenario_from_dict

REPO = Path(__file__).resolve().parents[1]
EARTH_LEO = (REPO / "scenes" / "earth_leo.toml").read_text()


def _scenario(tmp_path, trajectory_fov: str | None, camera: str, name: str = "leo.toml") -> Path:
    text = EARTH_LEO.replace("fov_deg = 30.0\n", "" if trajectory_fov is None else f"fov_deg = {trajectory_fov}\n")
    text = text.replace('[camera]\nwidth = 1024\nheight = 1024\nmodel = "pinhole"\n', f"[camera]\n{camera}\n")
    assert "[camera]\n" + camera in text
    p = tmp_path / name
    p.write_text(text)
    return p


def _plan_camera(sc):
    from renderlab.worlds.earth.plan import EarthPlan

    plan = EarthPlan.from_scenario(sc.model_copy(update={"trajectory": sc.trajectory.model_copy(
        update={"frames": 1})}))
    return plan.frames[0].camera


def _opencv_pixels(fx, fy, cx, cy, pts):
    import cv2

    K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
    uv, _ = cv2.projectPoints(pts.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, np.zeros(5))
    return uv.reshape(-1, 2)


def test_camera_fx_is_the_earth_camera_not_a_30_degree_default(tmp_path):
    """Fails before the change: ``trajectory.fov_deg`` defaulted to 30° and replaced camera.fx = 600 by 477.7 px
    (a 30° pinhole at 256 px) without a word; now the world renders through the camera the scenario gives."""
    sc, _ = load_scenario(_scenario(tmp_path, None, "width = 256\nheight = 192\nfx = 600.0\nfy = 610.0\n"
                                    "cx = 120.25\ncy = 100.75"))
    cam = _plan_camera(sc)
    pts = np.array([[0.01, -0.02, 1.0], [0.1, 0.05, 1.0], [-0.15, 0.12, 2.0]])
    ref = _opencv_pixels(600.0, 610.0, 120.25, 100.75, pts)
    assert np.max(np.abs(cam.project(pts) - ref)) < 1e-9
    assert sc.trajectory.fov_deg is None


def test_trajectory_fov_and_a_disagreeing_camera_are_refused_with_one_line(tmp_path, capsys):
    """Fails before the change: both keys loaded and the trajectory's 30° silently won over camera.fx = 600."""
    for camera, key in (("width = 256\nheight = 256\nfx = 600.0\nfy = 600.0", "fx"),
                        ("width = 256\nheight = 256\nfov_deg = 20.0", "fov_deg"),
                        ("width = 256\nheight = 256\ncx = 100.0", "cx")):
        path = _scenario(tmp_path, "30.0", camera)
        assert main(["show", str(path)]) == 2
        err = capsys.readouterr().err.strip()
        assert "\n" not in err and err.startswith("renderlab: error: leo.toml: trajectory.fov_deg = 30")
        assert f"disagrees with camera.{key} =" in err
        with pytest.raises(UserError, match="give the field of view once"):
            scenario_from_dict({"world": {"kind": "earth"}, "trajectory": {"kind": "leo", "fov_deg": 30.0},
                                "camera": {"width": 256, "height": 256, "fx": 600.0, "fy": 600.0}})


@pytest.mark.parametrize("name", ["earth_leo", "coastline_ekf", "coastline_image"])
def test_published_scenarios_keep_their_30_degree_camera(name):
    """The built-in scenes say ``trajectory.fov_deg = 30``: they load to the same centred 30° pinhole as before,
    held by the camera section, and the validated scenario reloads to itself (manifests, campaign runs)."""
    sc, _ = load_scenario(REPO / "scenes" / f"{name}.toml")
    c = sc.camera
    f = (c.width / 2) / math.tan(math.radians(15.0))
    assert abs(c.fx - f) < 1e-9 * f and abs(c.fy - f) < 1e-9 * f
    assert (c.cx, c.cy, c.skew, c.skew_yx) == ((c.width - 1) / 2, (c.height - 1) / 2, 0.0, 0.0)
    assert sc.trajectory.fov_deg is None
    again = scenario_from_dict(sc.to_dict())
    assert again.to_dict() == sc.to_dict()


def test_one_spelling_at_a_time_and_the_default(tmp_path):
    """The older key alone still sets the field of view; the same value in both places is accepted; a scenario
    without any focal length keeps the Earth camera's 30° default (now written into the camera)."""
    sc, _ = load_scenario(REPO / "scenes" / "earth_leo.toml", ["trajectory.fov_deg=20"])
    assert abs(sc.camera.fx - 512 / math.tan(math.radians(10))) < 1e-6
    sc, _ = load_scenario(REPO / "scenes" / "earth_leo.toml", ["camera.fov_deg=30.0"])
    assert abs(sc.camera.fx - 512 / math.tan(math.radians(15))) < 1e-6
    with pytest.raises(UserError, match=r"^earth_leo.toml: trajectory.fov_deg = 30 .* camera.fov_deg = 20"):
        load_scenario(REPO / "scenes" / "earth_leo.toml", ["camera.fov_deg=20"])
    sc, _ = load_scenario(_scenario(tmp_path, None, "width = 200\nheight = 100"))
    assert abs(sc.camera.fx - 100 / math.tan(math.radians(15))) < 1e-9 and sc.camera.cx == 99.5
    sc, _ = load_scenario(_scenario(tmp_path, None, "width = 200\nheight = 100\nfov_deg = 12.0"))
    assert abs(sc.camera.fx - 100 / math.tan(math.radians(6))) < 1e-9
