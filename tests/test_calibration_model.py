"""A calibration whose distortion model cannot be told is refused unless it is declared.

Four coefficients are ``cv2.projectPoints``' ``(k1, k2, p1, p2)`` or ``cv2.fisheye``'s ``(k1, k2, k3, k4)``. A
``cv2.fisheye.calibrate`` user who saves K and D with ``cv2.FileStorage`` and no flag used to get Brown — pixels to
hundreds of pixels off (measured below against ``cv2.fisheye.projectPoints``). Now such a file is refused with one
line, and read once the model is declared by the file (``fisheye_model``/``fisheye``, ``distortion_model``) or by the
scenario (``camera.calibration_model``); the oracles are ``cv2.fisheye.projectPoints`` and ``cv2.projectPoints``."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from renderlab.cli import main
from renderlab.errors import UserError
from renderlab.geometry import CameraModel
from renderlab.geometry.calibration import camera_from_opencv, read_calibration
from renderlab.scenario import load_scenario

SIZE = (1280, 960)


@pytest.fixture(scope="module")
def fisheye_kd():
    """K, D from ``cv2.fisheye.calibrate`` on a checkerboard seen in 15 seeded poses through a known fisheye."""
    rng = np.random.default_rng(7)
    K0 = np.array([[420.0, 0.0, 639.5], [0.0, 421.0, 479.5], [0.0, 0.0, 1.0]])
    D0 = np.array([0.045, -0.012, 0.004, -0.0008]).reshape(4, 1)
    board = np.zeros((1, 54, 3))
    board[0, :, :2] = np.mgrid[0:9, 0:6].T.reshape(-1, 2) * 0.04
    objs, imgs = [], []
    while len(objs) < 15:
        rvec = rng.normal(0.0, 0.5, 3)
        tvec = np.array([rng.uniform(-0.3, 0.1), rng.uniform(-0.2, 0.05), rng.uniform(0.3, 0.7)])
        p, _ = cv2.fisheye.projectPoints(board, rvec, tvec, K0, D0)
        if np.all((p[..., 0] > 0) & (p[..., 0] < SIZE[0]) & (p[..., 1] > 0) & (p[..., 1] < SIZE[1])):
            objs.append(board.copy())
            imgs.append(p)
    flags = cv2.fisheye.CALIB_RECOMPUTE_EXTRINSIC | cv2.fisheye.CALIB_FIX_SKEW
    _, K, D, _, _ = cv2.fisheye.calibrate(objs, imgs, SIZE, np.eye(3), np.zeros((4, 1)), flags=flags)
    assert D.shape == (4, 1) and np.allclose(D.ravel(), D0.ravel(), atol=1e-6)
    return K, D


def _save(path: Path, K, D, **extra) -> Path:
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    fs.write("image_width", SIZE[0])
    fs.write("image_height", SIZE[1])
    fs.write("K", K)
    fs.write("D", D)
    for key, value in extra.items():
        fs.write(key, value)
    fs.release()
    return path


def _rays(max_deg: float = 60.0) -> np.ndarray:
    th = np.radians(np.linspace(1.0, max_deg, 60))
    ph = np.linspace(0.0, 2 * np.pi, 60)
    return np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], -1) * 3.0


def _fisheye_px(K, D, pts):
    uv, _ = cv2.fisheye.projectPoints(pts.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, D)
    return uv.reshape(-1, 2)


@pytest.mark.parametrize("ext", ["yaml", "json"])
def test_an_undeclared_four_coefficient_file_is_refused(tmp_path, fisheye_kd, ext):
    """Fails before the change: the file was read as Brown. What that cost a cv2.fisheye user is measured here:
    4-39 px at 20-35° off axis, ~290 px at 60°."""
    K, D = fisheye_kd
    pts = _rays()
    brown, _ = cv2.projectPoints(pts.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, D.ravel())
    err = np.linalg.norm(brown.reshape(-1, 2) - _fisheye_px(K, D, pts), axis=1)
    off = np.degrees(np.arccos(pts[:, 2] / 3.0))
    assert err[(off > 19) & (off < 36)].min() > 4.0 and err.max() > 250.0
    path = _save(tmp_path / f"fisheye.{ext}", K, D)
    with pytest.raises(UserError, match=r"^fisheye\.\w+: distortion_coefficients: 4 coefficients are either "
                                        r"OpenCV's .* and nothing says which; declare the model") as info:
        read_calibration(path)
    assert "camera.calibration_model" in str(info.value) and "\n" not in str(info.value)
    with pytest.raises(UserError, match="4 coefficients are either"):
        camera_from_opencv(K, D)


def _scenario(tmp_path, calibration: str, model: str | None) -> Path:
    line = "" if model is None else f'calibration_model = "{model}"\n'
    text = (f'[world]\nkind = "analytic"\n[[world.bodies]]\nname = "s"\nshape = "sphere"\nradius_m = 1.0\n'
            f'[camera]\ncalibration_file = "{calibration}"\n{line}')
    p = tmp_path / "sc.toml"
    p.write_text(text)
    return p


@pytest.mark.parametrize("declared", ["equidistant", "fisheye", "kannala_brandt"])
def test_the_scenario_declares_the_fisheye_model(tmp_path, fisheye_kd, declared):
    K, D = fisheye_kd
    _save(tmp_path / "cal.yaml", K, D)
    sc, _ = load_scenario(_scenario(tmp_path, "cal.yaml", declared))
    cam = CameraModel.from_dict(sc.camera.model_dump())
    assert sc.camera.model == "kannala_brandt"
    pts = _rays(85.0)
    assert np.abs(cam.project(pts) - _fisheye_px(K, D, pts)).max() < 1e-9


@pytest.mark.parametrize("declared", ["plumb_bob", "radtan", "brown", "opencv"])
def test_the_scenario_declares_opencv_four_coefficients(tmp_path, declared):
    K = np.array([[612.3, 0.0, 318.7], [0.0, 609.8, 243.1], [0.0, 0.0, 1.0]])
    D = np.array([[-0.2, 0.04, 1e-3, -1e-3]])
    _save(tmp_path / "cal.yaml", K, D)
    sc, _ = load_scenario(_scenario(tmp_path, "cal.yaml", declared))
    assert sc.camera.model == "brown"
    pts = _rays(28.0)
    ref, _ = cv2.projectPoints(pts.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, D)
    assert np.abs(CameraModel.from_dict(sc.camera.model_dump()).project(pts) - ref.reshape(-1, 2)).max() < 1e-9


@pytest.mark.parametrize("flag, name", [("fisheye_model", 1), ("fisheye", 1), ("distortion_model", "equidistant")])
def test_the_file_declares_the_fisheye_model(tmp_path, fisheye_kd, flag, name):
    K, D = fisheye_kd
    cam = CameraModel.from_dict(read_calibration(_save(tmp_path / "f.yaml", K, D, **{flag: name})))
    pts = _rays(85.0)
    assert cam.model == "kannala_brandt" and np.abs(cam.project(pts) - _fisheye_px(K, D, pts)).max() < 1e-9
    assert read_calibration(_save(tmp_path / "b.yaml", K, D, fisheye_model=0))["model"] == "brown"


def test_a_declaration_the_file_contradicts_is_refused_with_one_line(tmp_path, fisheye_kd, capsys):
    K, D = fisheye_kd
    _save(tmp_path / "cal.yaml", K, D, fisheye_model=1)
    assert main(["show", str(_scenario(tmp_path, "cal.yaml", "plumb_bob"))]) == 2
    err = capsys.readouterr().err.strip()
    assert err == ("renderlab: error: sc.toml: camera.calibration_file: cal.yaml: the file says fisheye flag 1 but the "
                   "model declared for it (camera.calibration_model) is 'plumb_bob'; they must agree")
    _save(tmp_path / "cal.yaml", K, D, distortion_model="plumb_bob")
    with pytest.raises(UserError, match="the file says distortion_model: plumb_bob but the model declared"):
        load_scenario(_scenario(tmp_path, "cal.yaml", "equidistant"))
    with pytest.raises(UserError, match="calibration model 'double_sphere' is not one of plumb_bob"):
        load_scenario(_scenario(tmp_path, "cal.yaml", "double_sphere"))
    _save(tmp_path / "cal.yaml", K, D, fisheye_model=0, distortion_model="equidistant")
    with pytest.raises(UserError, match="the fisheye flag says 0 but the model is 'equidistant'"):
        read_calibration(tmp_path / "cal.yaml")
    p = tmp_path / "nofile.toml"
    p.write_text('[world]\nkind = "analytic"\n[[world.bodies]]\nname = "s"\nshape = "sphere"\nradius_m = 1.0\n'
                 '[camera]\ncalibration_model = "equidistant"\n')
    with pytest.raises(UserError, match="calibration_model declares the model of camera.calibration_file, which is "
                                        "not given"):
        load_scenario(p)
