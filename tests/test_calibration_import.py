"""Calibration import: OpenCV ``cv2.FileStorage`` (YAML, JSON) and ROS ``camera_info`` files → the camera
model, projecting like ``cv2.projectPoints`` / ``cv2.fisheye.projectPoints`` to 1e-9 px; the scenario's
``camera.calibration_file`` and ``camera.fov_deg``; bad files refused with one line."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from renderlab.errors import UserError
from renderlab.geometry import CameraModel
from renderlab.geometry.calibration import read_calibration
from renderlab.scenario import load_scenario, scenario_from_dict
from renderlab.scenario.camera import resolve_camera

yaml = pytest.importorskip("yaml")

REPO = Path(__file__).resolve().parents[1]
PX_TOL = 1e-9
K = np.array([[612.3, 0.0, 318.7], [0.0, 609.8, 243.1], [0.0, 0.0, 1.0]])
VECTORS = {
    5: [-0.28, 0.09, 1.1e-3, -6e-4, -0.012],
    8: [-0.21, 0.05, 8e-4, -5e-4, -0.01, 0.09, 0.02, -0.003],
    12: [-0.21, 0.05, 8e-4, -5e-4, -0.01, 0.09, 0.02, -0.003, 1e-3, -2e-4, 6e-4, 1e-4],
    14: [-0.21, 0.05, 8e-4, -5e-4, -0.01, 0.09, 0.02, -0.003, 1e-3, -2e-4, 6e-4, 1e-4, 0.012, -0.018],
}
FISHEYE = [0.021, -0.006, 0.0011, -0.0002]


def _write_opencv(path: Path, K: np.ndarray, D: np.ndarray, size=(640, 480), **extra) -> Path:
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    fs.write("image_width", size[0])
    fs.write("image_height", size[1])
    fs.write("camera_matrix", K)
    fs.write("distortion_coefficients", D)
    for key, value in extra.items():
        fs.write(key, value)
    fs.release()
    return path


def _points(rng: np.random.Generator, n: int = 2000, half_angle_deg: float = 28.0) -> np.ndarray:
    theta = np.radians(half_angle_deg) * np.sqrt(rng.uniform(0, 1, n))
    phi = rng.uniform(0, 2 * np.pi, n)
    d = np.column_stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)])
    return d * rng.uniform(0.5, 40.0, (n, 1))


def _check_projects_like_opencv(cam: CameraModel, K: np.ndarray, D, fisheye: bool = False) -> float:
    pts = _points(np.random.default_rng(3), half_angle_deg=70.0 if fisheye else 28.0)
    ours = cam.project(pts)
    if fisheye:
        ref, _ = cv2.fisheye.projectPoints(pts.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, np.asarray(D, float))
    else:
        ref, _ = cv2.projectPoints(pts.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, np.asarray(D, float))
    err = float(np.abs(ours - ref.reshape(-1, 2)).max())
    assert err <= PX_TOL, err
    return err


# ------------------------------------------------------------------ OpenCV FileStorage files
@pytest.mark.parametrize("ext", ["yaml", "json"])
@pytest.mark.parametrize("n", sorted(VECTORS))
def test_filestorage_calibration_projects_like_cv2(tmp_path, ext, n):
    D = np.array(VECTORS[n]).reshape(1, -1)
    path = _write_opencv(tmp_path / f"cal.{ext}", K, D)
    cam_dict = read_calibration(path)
    assert (cam_dict["width"], cam_dict["height"]) == (640, 480)
    assert cam_dict["model"] == ("brown" if n == 5 else "opencv")
    _check_projects_like_opencv(CameraModel.from_dict(cam_dict), K, D)


@pytest.mark.parametrize("ext", ["yaml", "json"])
def test_filestorage_fisheye_calibration_projects_like_cv2_fisheye(tmp_path, ext):
    D = np.array(FISHEYE).reshape(4, 1)  # cv2.fisheye.calibrate returns a 4x1 vector
    path = _write_opencv(tmp_path / f"fish.{ext}", K, D, fisheye_model=1)
    cam_dict = read_calibration(path)
    assert cam_dict["model"] == "kannala_brandt"
    _check_projects_like_opencv(CameraModel.from_dict(cam_dict), K, D, fisheye=True)


def test_filestorage_short_key_names_and_four_coefficients(tmp_path):
    fs = cv2.FileStorage(str(tmp_path / "k.yml"), cv2.FILE_STORAGE_WRITE)
    fs.write("K", K)
    fs.write("D", np.array([[-0.2, 0.04, 1e-3, -1e-3]]))
    fs.write("fisheye_model", 0)  # 4 coefficients: the model must be declared (tests/test_calibration_model.py)
    fs.release()
    cam_dict = read_calibration(tmp_path / "k.yml")
    assert "width" not in cam_dict and cam_dict["model"] == "brown" and cam_dict["distortion"]["p2"] == -1e-3
    _check_projects_like_opencv(CameraModel.from_dict({**cam_dict, "width": 640, "height": 480}), K,
                                [-0.2, 0.04, 1e-3, -1e-3])


# ------------------------------------------------------------------ ROS camera_info
def _ros_yaml(path: Path, model: str, D, K=K, size=(640, 480)) -> Path:
    data = {"image_width": size[0], "image_height": size[1], "camera_name": "navcam",
            "camera_matrix": {"rows": 3, "cols": 3, "data": np.asarray(K).ravel().tolist()},
            "distortion_model": model,
            "distortion_coefficients": {"rows": 1, "cols": len(D), "data": list(D)},
            "rectification_matrix": {"rows": 3, "cols": 3, "data": np.eye(3).ravel().tolist()},
            "projection_matrix": {"rows": 3, "cols": 4, "data": np.c_[K, np.zeros(3)].ravel().tolist()}}
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


@pytest.mark.parametrize("model, D, fisheye, ours", [
    ("plumb_bob", VECTORS[5], False, "brown"),
    ("rational_polynomial", VECTORS[8], False, "opencv"),
    ("equidistant", FISHEYE, True, "kannala_brandt"),
])
def test_ros_camera_info_projects_like_cv2(tmp_path, model, D, fisheye, ours):
    cam_dict = read_calibration(_ros_yaml(tmp_path / "navcam.yaml", model, D))
    assert cam_dict["model"] == ours
    _check_projects_like_opencv(CameraModel.from_dict(cam_dict), K, D, fisheye=fisheye)


def test_ros_message_form_flat_lists(tmp_path):
    p = tmp_path / "msg.yaml"
    p.write_text(yaml.safe_dump({"height": 480, "width": 640, "distortion_model": "plumb_bob",
                                 "D": VECTORS[5], "K": K.ravel().tolist()}))
    _check_projects_like_opencv(CameraModel.from_dict(read_calibration(p)), K, VECTORS[5])


# ------------------------------------------------------------------ bad files: one line naming the problem
def _bad_cases(tmp_path: Path) -> dict[str, tuple[Path, str]]:
    cases = {}
    fs = cv2.FileStorage(str(tmp_path / "noK.yaml"), cv2.FILE_STORAGE_WRITE)
    fs.write("distortion_coefficients", np.zeros((1, 5)))
    fs.release()
    cases["missing K"] = (tmp_path / "noK.yaml", r"noK.yaml: no camera matrix")
    cases["wrong shape"] = (_write_opencv(tmp_path / "k23.yaml", K[:2], np.zeros((1, 5))),
                            r"k23.yaml: camera_matrix must be 3x3, got 2x3")
    k_nan = K.copy()
    k_nan[0, 2] = np.nan
    cases["NaN yaml"] = (_write_opencv(tmp_path / "nan.yaml", k_nan, np.zeros((1, 5))), r"nan.yaml: .*finite")
    cases["NaN json"] = (_write_opencv(tmp_path / "nan.json", K, np.array([[0.1, np.nan, 0, 0, 0]])),
                         r"nan.json: distortion_coefficients must be finite")
    cases["unknown model"] = (_ros_yaml(tmp_path / "ds.yaml", "double_sphere", [0.1, 0.2]),
                              r"ds.yaml: distortion_model 'double_sphere' is not one of plumb_bob")
    cases["vector length"] = (_write_opencv(tmp_path / "d6.yaml", K, np.zeros((1, 6))),
                              r"d6.yaml: distortion_coefficients has 6 coefficients")
    cases["fisheye length"] = (_write_opencv(tmp_path / "f5.yaml", K, np.zeros((1, 5)), fisheye_model=1),
                               r"f5.yaml: distortion_coefficients: a fisheye model has 4 coefficients")
    k_row = K.copy()
    k_row[2] = [0.0, 0.1, 1.0]
    cases["last row"] = (_write_opencv(tmp_path / "row.yaml", k_row, np.zeros((1, 5))), r"last row must be")
    (tmp_path / "junk.yaml").write_text("camera_matrix: [1, 2\n  image_width: :")
    cases["not yaml"] = (tmp_path / "junk.yaml", r"junk.yaml: not valid YAML")
    (tmp_path / "list.json").write_text("[1, 2, 3]")
    cases["not a table"] = (tmp_path / "list.json", r"list.json: a calibration file must hold a table")
    (tmp_path / "cal.xml").write_text("<?xml version='1.0'?><opencv_storage></opencv_storage>")
    cases["xml"] = (tmp_path / "cal.xml", r"cal.xml: XML calibration files are not read")
    cases["missing"] = (tmp_path / "nope.yaml", r"calibration file not found")
    text = _ros_yaml(tmp_path / "rc.yaml", "plumb_bob", VECTORS[5]).read_text().replace("rows: 3\n  cols: 3", "rows: 3\n  cols: 4", 1)
    (tmp_path / "rc.yaml").write_text(text)
    cases["rows cols"] = (tmp_path / "rc.yaml", r"rc.yaml: camera_matrix says 3x4 but holds 9 numbers")
    return cases


@pytest.mark.parametrize("case", ["missing K", "wrong shape", "NaN yaml", "NaN json", "unknown model",
                                  "vector length", "fisheye length", "last row", "not yaml", "not a table", "xml",
                                  "missing", "rows cols"])
def test_bad_calibration_files_give_one_line(tmp_path, case):
    path, pattern = _bad_cases(tmp_path)[case]
    with pytest.raises(UserError, match=pattern) as info:
        read_calibration(path)
    assert "\n" not in str(info.value)


# ------------------------------------------------------------------ the scenario: camera.calibration_file, fov_deg
def _scenario_file(tmp_path: Path, camera_toml: str, name: str = "scene.toml") -> Path:
    text = (REPO / "scenes" / "analytic_sphere_box.toml").read_text()
    start = text.index("[camera]")
    end = text.index("\n[", start + 1)
    path = tmp_path / name
    path.write_text(text[:start] + "[camera]\n" + camera_toml + "\n" + text[end:])
    return path


def test_scenario_calibration_file_resolves_once_to_plain_intrinsics(tmp_path):
    (tmp_path / "cal").mkdir()
    D = np.array(VECTORS[14]).reshape(1, -1)
    _write_opencv(tmp_path / "cal" / "navcam.json", K, D)
    sc, base = load_scenario(_scenario_file(tmp_path, 'calibration_file = "cal/navcam.json"'))
    cam = sc.to_dict()["camera"]  # what the manifest stores: plain intrinsics, no file reference
    assert "calibration_file" not in cam and cam["model"] == "opencv" and (cam["width"], cam["height"]) == (640, 480)
    assert cam["fx"] == K[0, 0] and cam["cy"] == K[1, 2]
    _check_projects_like_opencv(CameraModel.from_dict(sc.camera.model_dump()), K, D)
    # the resolved scenario validates again as it is (campaign tasks, manifests)
    assert scenario_from_dict(sc.to_dict()).camera == sc.camera


def test_scenario_calibration_file_refusals(tmp_path):
    _write_opencv(tmp_path / "navcam.yaml", K, np.array(VECTORS[5]).reshape(1, -1))
    both = _scenario_file(tmp_path, 'calibration_file = "navcam.yaml"\nfx = 600.0', "both.toml")
    with pytest.raises(UserError, match=r"^both.toml: camera.calibration_file and camera.fx are both given"):
        load_scenario(both)
    size = _scenario_file(tmp_path, 'calibration_file = "navcam.yaml"\nwidth = 320', "size.toml")
    with pytest.raises(UserError, match=r"^size.toml: camera.width = 320 but the calibration file navcam.yaml"):
        load_scenario(size)
    gone = _scenario_file(tmp_path, 'calibration_file = "nope.yaml"', "gone.toml")
    with pytest.raises(UserError, match=r"^gone.toml: camera.calibration_file: calibration file not found"):
        load_scenario(gone)
    with pytest.raises(UserError, match=r"camera: calibration_file is read when the scenario file is loaded"):
        scenario_from_dict({"world": {"bodies": [{"name": "s", "shape": "sphere", "radius_m": 1.0}]},
                            "camera": {"calibration_file": "navcam.yaml"}})


def test_scenario_fov_deg_sets_a_centred_square_pixel_camera(tmp_path):
    sc, _ = load_scenario(_scenario_file(tmp_path, "width = 320\nheight = 240\nfov_deg = 60.0"))
    f = 160.0 / math.tan(math.radians(30.0))
    assert (sc.camera.fx, sc.camera.fy, sc.camera.cx, sc.camera.cy) == (f, f, 159.5, 119.5)
    ref = CameraModel.from_fov(320, 240, 60.0)
    assert CameraModel.from_dict(sc.camera.model_dump()) == ref
    # without the loader (scenario data validated directly) it is the same
    data = resolve_camera({"camera": {"width": 320, "height": 240, "fov_deg": 60.0}}, tmp_path)
    assert data["camera"] == {"width": 320, "height": 240, "fx": f, "fy": f, "cx": 159.5, "cy": 119.5}
    bad = _scenario_file(tmp_path, "fov_deg = 60.0\nfy = 300.0", "bad.toml")
    with pytest.raises(UserError, match=r"^bad.toml: camera.fov_deg and camera.fy are both given"):
        load_scenario(bad)
    with pytest.raises(UserError, match=r"camera: fov_deg must be a number in \(0, 180\)"):
        scenario_from_dict({"world": {"bodies": [{"name": "s", "shape": "sphere", "radius_m": 1.0}]},
                            "camera": {"fov_deg": 190.0}})
