"""Camera calibration files → the camera dict of :class:`~renderlab.geometry.camera.CameraModel`.

Two kinds of file are read:

- an OpenCV calibration written by ``cv2.FileStorage`` as YAML (``%YAML:1.0`` header, ``!!opencv-matrix``
  nodes) or JSON (``type_id: opencv-matrix`` nodes): the camera matrix under ``camera_matrix`` / ``K`` /
  ``cameraMatrix``, the distortion vector under ``distortion_coefficients`` / ``D`` / ``distCoeffs``, the
  size under ``image_width`` / ``image_height``, and the fisheye flag ``fisheye_model: 1`` / ``0`` (also
  ``fisheye``, or a ``distortion_model`` string as below);
- a ROS ``camera_info`` YAML (``camera_calibration_parsers``): ``image_width``, ``image_height``,
  ``camera_matrix: {rows, cols, data}``, ``distortion_model`` (``plumb_bob``, ``rational_polynomial`` or
  ``equidistant``) and ``distortion_coefficients: {rows, cols, data}``; the flat message form
  (``width``, ``height``, ``K`` / ``k``, ``D`` / ``d``) is read too.

OpenCV distortion vectors map onto the lab's models by length: 5 coefficients ``(k1, k2, p1, p2, k3)`` →
``brown``; 8, 12 or 14 ``(k1, k2, p1, p2, k3, k4, k5, k6[, s1..s4[, tau_x, tau_y]])`` → ``opencv``; none →
``pinhole``. Four coefficients are either ``cv2.projectPoints``' ``(k1, k2, p1, p2)`` (``brown``) or
``cv2.fisheye``'s ``(k1, k2, k3, k4)`` (``kannala_brandt``), which differ by pixels to tens of pixels: such a
vector is read only when the model is declared — by the file (``fisheye_model`` / ``fisheye``: 1 or 0, or a
``distortion_model`` name) or by the caller (``model``; the scenario's ``camera.calibration_model``), and the
two must agree. Declared names (:data:`MODEL_NAMES`): ``plumb_bob``, ``radtan``, ``brown``, ``opencv``,
``rational_polynomial`` (OpenCV's vector), ``equidistant``, ``fisheye``, ``kannala_brandt`` (``cv2.fisheye``),
``none``, ``pinhole``.
OpenCV and ROS put pixel centres at integers with (0, 0) the centre of the top-left pixel, as the lab does, so the
camera matrix is used as it is: ``fx = K[0,0]``, ``skew = K[0,1]``, ``cx = K[0,2]``, ``skew_yx = K[1,0]``,
``fy = K[1,1]``, ``cy = K[1,2]``.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from renderlab.errors import UserError
from renderlab.inputs import LIMITS, PIXEL_MAX, load_yaml, read_text, short

from .camera import CameraModel
from .distortion_opencv import KEYS as OPENCV_KEYS
from .fisheye import KEYS as FISHEYE_KEYS

__all__ = ["MODEL_NAMES", "read_calibration", "camera_from_opencv", "opencv_intrinsics"]

#: the largest |number| a calibration file may hold (intrinsics in px, distortion coefficients)
VALUE_MAX = PIXEL_MAX
_K_KEYS = ("camera_matrix", "K", "k", "cameraMatrix")
_D_KEYS = ("distortion_coefficients", "D", "d", "distCoeffs", "dist_coeffs")
_W_KEYS, _H_KEYS = ("image_width", "width"), ("image_height", "height")
#: ``distortion_model`` names (ROS, OpenCV tools) → the lab's model; ``None``: decide by the vector length
_MODEL_NAMES = {"plumb_bob": "brown", "radtan": None, "brown": None, "opencv": None, "rational_polynomial": "opencv",
                "equidistant": "kannala_brandt", "fisheye": "kannala_brandt", "kannala_brandt": "kannala_brandt",
                "none": "pinhole", "pinhole": None}
#: the distortion-model names a file (``distortion_model``) or the caller (``camera.calibration_model``) may declare
MODEL_NAMES = tuple(_MODEL_NAMES)
_DECLARE = ("declare the model: fisheye_model: 1 (cv2.fisheye) or 0, or distortion_model: plumb_bob | equidistant "
            "in the file, or camera.calibration_model in the scenario")
#: model → its coefficient names in OpenCV's vector order (``brown``: OpenCV's first five)
_VECTOR_ORDER = {"pinhole": (), "brown": ("k1", "k2", "p1", "p2", "k3"), "opencv": OPENCV_KEYS,
                 "kannala_brandt": FISHEYE_KEYS}


def _number(value: Any, name: str) -> float:
    """A finite float from a parsed scalar (OpenCV writes ``.Nan``/``.Inf``, which YAML 1.1 leaves as text)."""
    if isinstance(value, str):
        text = value.strip().lower().replace(".nan", "nan").replace(".inf", "inf")
        try:
            value = float(text)
        except ValueError:
            raise UserError(f"{name} must hold numbers, got {short(value)}") from None
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise UserError(f"{name} must hold numbers, got {short(value)}")
    if not math.isfinite(float(value)):
        raise UserError(f"{name} must be finite, got {float(value)!r}")
    if abs(float(value)) > VALUE_MAX:
        raise UserError(f"{name}: {float(value):g} is outside the physical range (|value| <= {VALUE_MAX:g})")
    return float(value)


def _matrix(node: Any, name: str) -> np.ndarray:
    """A 2-D float array from an OpenCV/ROS matrix node ``{rows, cols, data}``, a nested or a flat list."""
    if isinstance(node, np.ndarray):
        node = node.tolist()
    if isinstance(node, Mapping):
        if "data" not in node:
            raise UserError(f"{name} has no 'data'")
        data = node["data"]
        rows, cols = node.get("rows"), node.get("cols")
    else:
        data, rows, cols = node, None, None
    if not isinstance(data, Sequence) or isinstance(data, str):
        raise UserError(f"{name} must be a matrix (rows, cols, data) or a list of numbers, got {short(data)}")
    if data and all(isinstance(r, Sequence) and not isinstance(r, str) for r in data):  # nested list
        if len({len(r) for r in data}) != 1:
            raise UserError(f"{name} has rows of different lengths")
        rows, cols, data = len(data), len(data[0]), [v for r in data for v in r]
    values = [_number(v, name) for v in data]
    if rows is None or cols is None:
        rows, cols = 1, len(values)
    if not all(isinstance(n, int) and not isinstance(n, bool) and n >= 0 for n in (rows, cols)):
        raise UserError(f"{name} rows and cols must be non-negative integers, got {short(rows)} and {short(cols)}")
    if rows * cols != len(values):
        raise UserError(f"{name} says {rows}x{cols} but holds {len(values)} numbers")
    return np.array(values, dtype=np.float64).reshape(rows, cols)


def _model_for(n_coeffs: int, fisheye: bool | None, named: str | None, name: str, declared: bool) -> str:
    """The lab's model for a distortion vector of `n_coeffs` (no coefficients: ``pinhole``); four coefficients need a
    `declared` model (a fisheye flag or a model name)."""
    if n_coeffs == 4 and not declared:
        raise UserError(f"{name}: 4 coefficients are either OpenCV's (k1, k2, p1, p2) or cv2.fisheye's (k1, k2, k3, "
                        f"k4) and nothing says which; {_DECLARE}")
    if fisheye or named == "kannala_brandt":
        if n_coeffs not in (0, 4):
            raise UserError(f"{name}: a fisheye model has 4 coefficients (k1, k2, k3, k4), got {n_coeffs}")
        return "kannala_brandt"
    if n_coeffs == 0:
        return "pinhole"
    if named == "pinhole":
        raise UserError(f"{name}: distortion_model 'none' but {n_coeffs} coefficients")
    if named == "brown" and n_coeffs not in (4, 5):
        raise UserError(f"{name}: plumb_bob has 5 coefficients (k1, k2, p1, p2, k3), got {n_coeffs}")
    by_length = {4: "brown", 5: "brown", 8: "opencv", 12: "opencv", 14: "opencv"}
    if n_coeffs not in by_length:
        raise UserError(f"{name} has {n_coeffs} coefficients; OpenCV uses 4, 5, 8, 12 or 14 (fisheye: 4)")
    return by_length[n_coeffs]


def camera_from_opencv(K: Any, D: Any = None, width: int | None = None, height: int | None = None, *,
                       fisheye: bool | None = None, distortion_model: str | None = None,
                       where: str = "calibration") -> dict[str, Any]:
    """The lab's camera dict from an OpenCV / ROS camera matrix and distortion vector.

    Parameters
    ----------
    K : array_like or mapping
        3x3 camera matrix (nested or flat list, or a ``{rows, cols, data}`` node), last row ``(0, 0, 1)``.
    D : array_like or mapping, optional
        Distortion vector of 0, 4, 5, 8, 12 or 14 coefficients (fisheye: 4), any 1xN / Nx1 shape.
    width, height : int, optional
        Image size in pixels; left out of the result when None.
    fisheye : bool, optional
        True: the vector is ``cv2.fisheye``'s ``(k1, k2, k3, k4)``; False: it is ``cv2.projectPoints``'; None: not
        declared (then a 4-vector needs `distortion_model`).
    distortion_model : str, optional
        A name of :data:`MODEL_NAMES` (ROS: ``plumb_bob``, ``rational_polynomial``, ``equidistant``; also
        ``fisheye``, ``radtan``, ``none``...); it must agree with `fisheye` when both are given.
    where : str
        Prefix of error messages (the file name).

    Returns
    -------
    dict
        ``width``, ``height`` (when given), ``fx, fy, cx, cy, skew, skew_yx, model, distortion``; checked by
        building a :class:`CameraModel` when the size is known.

    Raises
    ------
    UserError
        Wrong shape, non-finite value, a camera matrix that is not ``[[fx, s, cx], [., fy, cy], [0, 0, 1]]``
        with positive ``fx, fy``, an unknown distortion model or a vector length the model does not have, four
        coefficients without a declared model, a fisheye flag that contradicts the model name.
    """
    k = _matrix(K, f"{where}: camera_matrix")
    if k.size != 9:
        raise UserError(f"{where}: camera_matrix must be 3x3, got {k.shape[0]}x{k.shape[1]}")
    k = k.reshape(3, 3)
    if not np.array_equal(k[2], [0.0, 0.0, 1.0]):
        raise UserError(f"{where}: camera_matrix last row must be [0, 0, 1], got {k[2].tolist()}")
    if not (k[0, 0] > 0 and k[1, 1] > 0):
        raise UserError(f"{where}: camera_matrix fx and fy must be > 0, got {k[0, 0]!r} and {k[1, 1]!r}")
    d = np.zeros((1, 0)) if D is None else _matrix(D, f"{where}: distortion_coefficients")
    if min(d.shape) > 1:
        raise UserError(f"{where}: distortion_coefficients must be one row or column, got {d.shape[0]}x{d.shape[1]}")
    d = d.ravel()
    named = None
    if distortion_model is not None:
        key = str(distortion_model).strip().lower()
        if key not in _MODEL_NAMES:
            raise UserError(f"{where}: distortion_model {short(distortion_model)} is not one of "
                            "plumb_bob, rational_polynomial, equidistant (or fisheye, radtan, none)")
        named = _MODEL_NAMES[key]
    if fisheye is not None and distortion_model is not None and bool(fisheye) != (named == "kannala_brandt"):
        raise UserError(f"{where}: the fisheye flag says {int(bool(fisheye))} but the model is "
                        f"{distortion_model!r}; they must agree")
    model = _model_for(d.size, fisheye, named, f"{where}: distortion_coefficients",
                       fisheye is not None or distortion_model is not None)
    names = _VECTOR_ORDER[model]
    out: dict[str, Any] = {} if width is None or height is None else {"width": width, "height": height}
    out.update(fx=float(k[0, 0]), fy=float(k[1, 1]), cx=float(k[0, 2]), cy=float(k[1, 2]),
               skew=float(k[0, 1]), skew_yx=float(k[1, 0]), model=model,
               distortion={n: float(v) for n, v in zip(names, d)})
    if "width" in out:
        try:
            CameraModel.from_dict(out)
        except UserError as err:
            raise UserError(f"{where}: {err}") from None
    return out


def opencv_intrinsics(camera: CameraModel) -> tuple[np.ndarray, np.ndarray, bool]:
    """``(K, D, fisheye)`` for ``cv2.projectPoints`` (or ``cv2.fisheye.projectPoints`` when `fisheye`).

    ``brown`` gives OpenCV's 5-vector ``(k1, k2, p1, p2, k3)``, ``opencv`` the 14-vector, ``kannala_brandt``
    the 4-vector; ``pinhole`` an empty vector. ``owen`` has no OpenCV form (UserError). ``cv2.projectPoints``
    ignores ``K[0, 1]`` and ``K[1, 0]``; the fisheye's ``alpha`` is ``skew / fx``.
    """
    if camera.model not in _VECTOR_ORDER:
        raise UserError(f"camera.model {short(camera.model)} has no OpenCV form")
    d = np.array([camera.distortion[n] for n in _VECTOR_ORDER[camera.model]])
    return camera.K_matrix, d, camera.model == "kannala_brandt"


def _load_text(path: Path) -> Mapping[str, Any]:
    name = path.name
    text = read_text(path, "calibration file", LIMITS["calibration"])  # a regular file of bounded size
    stripped = text.lstrip()
    if stripped.startswith("<"):
        raise UserError(f"{name}: XML calibration files are not read; write YAML or JSON with cv2.FileStorage")
    if path.suffix.lower() == ".json" or stripped.startswith("{"):
        text = re.sub(r"(?<![\w.\"])([-+]?)\.(Nan|NaN|nan|Inf|inf|INF)\b",
                      lambda m: "NaN" if m.group(2).lower() == "nan" else f"{m.group(1)}Infinity", text)
        try:
            data = json.loads(text)
        except json.JSONDecodeError as err:
            raise UserError(f"{name}: not valid JSON ({err.msg} at line {err.lineno})") from None
    else:
        data = _load_yaml(text, name)
    if not isinstance(data, Mapping):
        raise UserError(f"{name}: a calibration file must hold a table of keys, got {type(data).__name__}")
    return data


def _load_yaml(text: str, name: str) -> Any:
    import yaml

    class _Loader(yaml.SafeLoader):
        """SafeLoader that reads OpenCV's ``!!opencv-matrix`` (and other ``!!opencv-*``) nodes as tables."""

    _Loader.add_multi_constructor("tag:yaml.org,2002:opencv-",
                                  lambda loader, suffix, node: loader.construct_mapping(node, deep=True))
    text = re.sub(r"\A\s*%YAML:\S*[^\n]*\n", "", text)  # OpenCV's non-standard '%YAML:1.0' directive
    return load_yaml(text, _Loader, name)  # aliases expanded past a bound (an alias bomb) are refused


def _first(data: Mapping[str, Any], keys: Sequence[str]) -> tuple[str | None, Any]:
    for key in keys:
        if key in data:
            return key, data[key]
    return None, None


def _size(data: Mapping[str, Any], keys: Sequence[str], name: str) -> int | None:
    key, value = _first(data, keys)
    if key is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or value != int(value) or value <= 0:
        raise UserError(f"{name}: {key} must be a positive integer, got {short(value)}")
    return int(value)


def _flag(data: Mapping[str, Any], name: str) -> bool | None:
    """The file's fisheye flag (``fisheye_model`` or ``fisheye``: 1 or 0), None when it has none."""
    for key in ("fisheye_model", "fisheye"):
        if key in data:
            flag = data[key]
            if not isinstance(flag, (bool, int)) or flag not in (0, 1):
                raise UserError(f"{name}: {key} must be 0 or 1, got {short(flag)}")
            return bool(flag)
    return None


def _declared(model: str | None, flag: bool | None, model_name: str | None, name: str) -> str | None:
    """The caller's `model` checked against the file's own flag and name; the name to read the vector with."""
    if model is None:
        return model_name or None
    key = str(model).strip().lower()
    if key not in _MODEL_NAMES:
        raise UserError(f"calibration model {short(model)} is not one of {', '.join(MODEL_NAMES)}")
    fish = _MODEL_NAMES[key] == "kannala_brandt"
    file_named = _MODEL_NAMES.get(str(model_name).strip().lower()) if model_name else None
    clash = (flag is not None and flag != fish) or (
        model_name is not None and ((file_named == "kannala_brandt") != fish
                                    or None not in (file_named, _MODEL_NAMES[key]) and file_named != _MODEL_NAMES[key]))
    if clash:
        says = f"distortion_model: {model_name}" if model_name is not None else f"fisheye flag {int(flag)}"
        raise UserError(f"{name}: the file says {says} but the model declared for it (camera.calibration_model) is "
                        f"{model!r}; they must agree")
    return model_name or key


def read_calibration(path: str | Path, model: str | None = None) -> dict[str, Any]:
    """Read an OpenCV (``cv2.FileStorage`` YAML/JSON) or ROS ``camera_info`` calibration file.

    Parameters
    ----------
    path : str or Path
        The file; ``.json`` (or text starting with ``{``) is JSON, anything else YAML.
    model : str, optional
        The distortion model the caller declares for the file (a name of :data:`MODEL_NAMES`; the scenario's
        ``camera.calibration_model``): needed for a 4-coefficient vector whose file does not say whether it is
        ``cv2.fisheye``'s; it must agree with the file's own flag or name.

    Returns
    -------
    dict
        The camera dict (see :func:`camera_from_opencv`); ``width`` and ``height`` only when the file has them.

    Raises
    ------
    UserError
        One line naming the file and the problem: missing camera matrix, wrong shape, NaN, unknown
        distortion model, a model that cannot be told (4 coefficients, nothing declared), a declared model the file
        contradicts, unreadable file.
    """
    p = Path(path)
    data = _load_text(p)
    name = p.name
    k_key, K = _first(data, _K_KEYS)
    if k_key is None:
        raise UserError(f"{name}: no camera matrix (expected one of {', '.join(_K_KEYS)})")
    _, D = _first(data, _D_KEYS)
    flag = _flag(data, name)
    model_name = data.get("distortion_model")
    if model_name is not None and not isinstance(model_name, str):
        raise UserError(f"{name}: distortion_model must be a name, got {short(model_name)}")
    return camera_from_opencv(K, D, _size(data, _W_KEYS, name),
                              _size(data, _H_KEYS, name), fisheye=flag,
                              distortion_model=_declared(model, flag, model_name, name), where=name)
