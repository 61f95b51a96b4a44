"""Image files of truth sets: multi-channel EXR (OpenEXR package), 16-bit DN PNG and its 8-bit preview.

EXR: single part, scanline, lossless ZIP at zlib level :data:`EXR_ZIP_LEVEL`; float32 channels, except uint32
arrays, which are written as UINT channels (the body-id channel). The header holds no time stamps, so the same data give bit-identical
bytes; :func:`frame_exr_header` builds the per-frame camera/pose/units attributes. PNG: 16-bit grey holding
the N-bit DN values exactly, with an ``sBIT`` chunk saying N, plus an 8-bit preview scaled so that full
scale (2^N - 1) is 255; both deflated with zlib's run-length strategy (:data:`PNG_PARAMS`). A missing, truncated or corrupt file raises :class:`UserError` naming it.
"""

from __future__ import annotations

import concurrent.futures
import json
import os
import struct
import zlib
from pathlib import Path

import cv2
import numpy as np
import OpenEXR

from renderlab.contracts.image_headers import check_image
from renderlab.errors import UserError
from renderlab.files import openexr_lib
from renderlab.geometry.rotations import rotation_from_quat_xyzw
from renderlab.inputs import LIMITS, read_bytes, shown

_RESERVED_HEADER = {"channels", "compression", "dataWindow", "displayWindow", "lineOrder", "name",
                    "pixelAspectRatio", "screenWindowCenter", "screenWindowWidth", "type", "tiles",
                    "version", "chunkCount"}
_MAX_EXACT_ID = 2 ** 24  # float32 holds every integer of magnitude up to this exactly (old float-id files)
_ARRAY_ATTR_SHAPES = {(2,), (3,), (3, 3), (4, 4)}  # V2, V3, M33, M44 (f or d by dtype)
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
RADIANCE_UNIT = "W m^-2 sr^-1"
CHANNEL_UNITS = {"Y": RADIANCE_UNIT, "R": RADIANCE_UNIT, "G": RADIANCE_UNIT, "B": RADIANCE_UNIT,
                 "P.X": "m", "P.Y": "m", "P.Z": "m", "N.X": "1", "N.Y": "1", "N.Z": "1", "range": "m",
                 "id": "1"}
ID_ENCODING = ("UINT channel holding the int32 body id's two's-complement bit pattern: "
               "4294967295 (0xFFFFFFFF) = -1 = no hit; ids 0..2147483647 as they are")
QUAT_CONVENTION = ("renderlab:quat_render_from_cam_xyzw is scalar-last (x, y, z, w); it rotates camera-frame "
                   "vectors into the render frame: p_render = R(q) p_cam + renderlab:position_m; renderlab camera "
                   "frame: +x right (increasing sample), +y down (increasing line), +z boresight")


# ----------------------------------------------------------------------------------------- EXR
def _header_value(key, value):
    """Validated header attribute value (str, int, float or a float32/float64 V2/V3/M33/M44 array)."""
    if key in _RESERVED_HEADER or isinstance(value, bool):
        raise ValueError(f"write_exr: header attribute {key!r}={value!r} not allowed")
    if isinstance(value, (str, int, float)):
        return value
    if (isinstance(value, np.ndarray) and value.shape in _ARRAY_ATTR_SHAPES
            and value.dtype in (np.float32, np.float64) and np.all(np.isfinite(value))):
        return np.ascontiguousarray(value)
    raise ValueError(f"write_exr: header attribute {key!r}={value!r} not allowed")


#: zlib level of the EXR ZIP compression (OpenEXR's default is 4). Level 1, on real 1 MP EV5 frames (ten channels):
#: 0.32-0.37 s of CPU per file instead of 0.51 s, 23.27 MB instead of 22.18 MB (+5 %); still lossless
#: (``benchmarks/README.md``, ``bench_frame_api.py --file-settings``).
EXR_ZIP_LEVEL = 1
#: OpenCV's PNG options for the DN PNG and its preview: zlib's run-length strategy (Z_RLE) at level 1. On real 1 MP EV5
#: frames: 0.10 s and 0.90-0.97 MB per 16-bit DN PNG instead of 0.19-0.23 s and 0.92-0.96 MB with the default
#: strategy at level 3; the 8-bit preview 0.05-0.07 s and 0.37-0.45 MB instead of 0.11-0.12 s and 0.44-0.52 MB.
PNG_PARAMS = (cv2.IMWRITE_PNG_COMPRESSION, 1, cv2.IMWRITE_PNG_STRATEGY, cv2.IMWRITE_PNG_STRATEGY_RLE)


#: ``render.exr_compression`` → OpenEXR compression (all lossless): ``zip`` (default, smallest), ``rle`` (fast,
#: larger files: in-the-loop and scratch sets), ``none`` (fastest write, largest files)
EXR_COMPRESSIONS = ("zip", "rle", "none")


def write_exr(path, channels: dict, header_extra: dict | None = None, compression: str = "zip") -> None:
    """Write a single-part scanline EXR, lossless (``compression``: one of :data:`EXR_COMPRESSIONS`).

    The header holds only the standard attributes plus ``header_extra`` (no time stamps), so
    the same data give bit-identical files.

    Parameters
    ----------
    path : str or os.PathLike
        Output file.
    channels : dict of str to numpy.ndarray
        Channel name → (H, W) real array, all the same shape. ``uint32`` arrays become UINT
        channels; everything else is cast to float32 (FLOAT channels).
    header_extra : dict, optional
        Extra header attributes: str, int, float (stored as 32-bit float), or a finite float32 /
        float64 numpy array of shape (2,), (3,), (3, 3) or (4, 4) (V2f/V2d, V3f/V3d, M33f/M33d,
        M44f/M44d).
    compression : str
        ``"zip"`` (default; zlib level :data:`EXR_ZIP_LEVEL`), ``"rle"`` or ``"none"``: lossless, so every pixel
        reads back bit for bit.
    """
    if compression not in EXR_COMPRESSIONS:
        raise ValueError(f"write_exr: compression must be one of {EXR_COMPRESSIONS}, got {compression!r}")
    if not channels:
        raise ValueError("write_exr: no channels")
    data, shape = {}, None
    for name, arr in channels.items():
        a = np.asarray(arr)
        if a.ndim != 2 or not (np.issubdtype(a.dtype, np.number) or a.dtype == bool):
            raise ValueError(f"write_exr: channel {name!r} must be a real (H, W) array, got "
                             f"{a.dtype} {a.shape}")
        if shape is not None and a.shape != shape:
            raise ValueError(f"write_exr: channel {name!r} has shape {a.shape}, expected {shape}")
        shape = a.shape
        dtype = np.uint32 if a.dtype == np.uint32 else np.float32
        data[str(name)] = np.ascontiguousarray(a, dtype=dtype)  # C order is required
    codes = {"zip": OpenEXR.ZIP_COMPRESSION, "rle": OpenEXR.RLE_COMPRESSION, "none": OpenEXR.NO_COMPRESSION}
    header = {"compression": codes[compression], "type": OpenEXR.scanlineimage}
    for key, value in (header_extra or {}).items():
        header[str(key)] = _header_value(key, value)
    setter = openexr_lib.zip_level_setter() if compression == "zip" else None
    if setter is not None:
        setter(EXR_ZIP_LEVEL)  # read by the C++ header that write() builds
    try:
        threads = openexr_lib.exr_threads() if compression != "none" else 1  # nothing to compress: no pool
        with OpenEXR.File(header, data) as exr, openexr_lib.compression_threads(threads):
            exr.write(str(path))
    except (RuntimeError, OSError) as exc:
        raise UserError(f"cannot write EXR {path}: {exc}") from None


def read_exr(path, size: tuple[int, int] | None = None) -> dict:
    """Read every channel of an EXR (part 0): ``{name: (H, W) array}``.

    UINT channels come back as uint32, FLOAT and HALF channels as float32. The header is checked first (a regular
    file, a sane size and, with ``size`` = (width, height), that size: :func:`renderlab.contracts.image_headers.
    check_image`). A missing, truncated or corrupt file raises :class:`UserError` naming the file.
    """
    p = Path(path)
    if not os.path.lexists(p):
        raise UserError(f"EXR file not found: {shown(p)}")
    check_image(p, "EXR", size=size)
    try:
        with OpenEXR.File(str(p), separate_channels=True) as exr:
            out = {}
            for name, ch in exr.channels().items():
                uint = ch.type() == OpenEXR.UINT
                out[name] = np.asarray(ch.pixels, dtype=np.uint32 if uint else np.float32)
    except (RuntimeError, OSError, ValueError) as exc:
        raise UserError(f"corrupt or unreadable EXR {shown(p)}: {' '.join(str(exc).split())[:120]}") from None
    if not out or any(a.ndim != 2 for a in out.values()):
        raise UserError(f"EXR {shown(p)} has no channels or non-2-D channels")
    return out


def encode_ids(ids) -> np.ndarray:
    """Body ids (int32 values, -1 = no hit; any integer-valued dtype) → uint32 bit patterns for a UINT
    channel (``-1`` → 4294967295). ValueError for non-integer or out-of-int32 values."""
    a = np.asarray(ids)
    if a.size and not np.issubdtype(a.dtype, np.integer):
        if not np.all(np.isfinite(a)) or not np.all(a == np.rint(a)):
            raise ValueError("channel 'id' holds non-integer values")
    if a.size and (a.min() < -2 ** 31 or a.max() > 2 ** 31 - 1):
        raise ValueError("channel 'id' holds values outside the int32 range")
    return np.ascontiguousarray(a.astype(np.int64).astype(np.int32).view(np.uint32))


def decode_ids(arr: np.ndarray, where: str) -> np.ndarray:
    """An id channel as read by :func:`read_exr` → int32 ids: a UINT channel is reinterpreted
    (0xFFFFFFFF → -1); an old float32 channel must hold integers (UserError naming ``where``)."""
    if arr.dtype == np.uint32:
        return arr.view(np.int32)
    if not np.all(np.isfinite(arr)) or not np.all(arr == np.rint(arr)):
        raise UserError(f"EXR {where}: channel 'id' holds non-integer values")
    return arr.astype(np.int32)


def _homogeneous(M3x4: np.ndarray) -> np.ndarray:
    return np.vstack([M3x4, [0.0, 0.0, 0.0, 1.0]])


def _camera_attrs(camera: dict, cam_from_render: np.ndarray | None) -> dict:
    """``renderlab:K`` / ``renderlab:camera`` and, with a pose, the standard ``worldToNDC``."""
    K = np.array([[camera["fx"], camera.get("skew", 0.0), camera["cx"]],
                  [camera.get("skew_yx", 0.0), camera["fy"], camera["cy"]], [0.0, 0.0, 1.0]], float)
    out = {"renderlab:K": K, "renderlab:camera": json.dumps(camera, sort_keys=True)}
    if cam_from_render is not None and "width" in camera and "height" in camera:
        w, h = float(camera["width"]), float(camera["height"])
        # pixel (s, l), centres at integers → NDC: (0, 0) top-left corner, (1, 1) bottom-right corner
        ndc = np.array([[1 / w, 0.0, 0.5 / w], [0.0, 1 / h, 0.5 / h], [0.0, 0.0, 1.0]]) @ K
        P = ndc @ cam_from_render[:3]                       # rows: X, Y, W (W = depth z_cam)
        col = np.vstack([P[:2], cam_from_render[2], P[2]])  # Z = depth too, so Z/W = 1 (discarded)
        out["worldToNDC"] = np.ascontiguousarray(col.T, dtype=np.float32)  # OpenEXR: row vectors
    return out


def frame_exr_header(index: int, time_s: float, meta: dict, channels, *,
                     render_frame: str | None = None) -> dict:
    """Header attributes of one truth-set frame EXR (deterministic: no time stamps).

    Standard attributes (OpenEXR row-vector convention, ``[x y z 1] · M``): ``worldToCamera``
    (M44f; render frame → OpenEXR camera space: +x right, +y *up*, +z viewing direction, i.e. the
    renderlab camera frame with y negated), ``worldToNDC`` (M44f; pinhole part only: NDC (0, 0) and
    (1, 1) are the top-left and bottom-right corners of the image) and ``expTime`` (float, s).
    renderlab attributes: ``renderlab:camFromRender`` (M44d, column vectors, renderlab camera frame:
    ``[p_cam; 1] = M [p_render; 1]``), ``renderlab:K`` (M33d pixel map, pixel centres at integers),
    ``renderlab:camera`` (JSON camera dict with distortion), ``renderlab:position_m`` (V3d),
    ``renderlab:quat_render_from_cam_xyzw`` (JSON, exact) and ``renderlab:quat_convention``,
    ``renderlab:frame`` (render frame name), ``renderlab:frame_index`` (int), ``renderlab:time_s``
    (exact decimal text), ``renderlab:epoch`` (UTC ISO 8601, when the world has one),
    ``renderlab:units`` (``"name=unit; ..."`` per channel) and ``renderlab:id_encoding``.

    Parameters
    ----------
    index : int
        Frame index.
    time_s : float
        Frame time, s.
    meta : dict
        The frame record (``camera``, ``pose``, ``sensor``, ``epoch_utc``, ``render_frame``: each optional).
    channels : iterable of str
        Channel names in the file.
    render_frame : str, optional
        Render frame name when ``meta`` has no ``render_frame``.
    """
    names = list(channels)
    hdr = {"renderlab:frame_index": int(index), "renderlab:time_s": repr(float(time_s)),
           "renderlab:units": "; ".join(f"{c}={CHANNEL_UNITS[c]}" for c in sorted(names) if c in CHANNEL_UNITS)}
    if "id" in names:
        hdr["renderlab:id_encoding"] = ID_ENCODING
    rf = meta.get("render_frame")
    name = rf.get("name") if isinstance(rf, dict) else render_frame
    if name is not None:
        hdr["renderlab:frame"] = str(name)
    if meta.get("epoch_utc") is not None:
        hdr["renderlab:epoch"] = str(meta["epoch_utc"])
    sensor = meta.get("sensor") or {}
    if "exposure_s" in sensor:
        hdr["expTime"] = float(sensor["exposure_s"])
    cam_from_render, pose = None, meta.get("pose")
    if pose and "position_m" in pose and "quat_render_from_cam_xyzw" in pose:
        q, t = pose["quat_render_from_cam_xyzw"], np.asarray(pose["position_m"], float)
        Rt = rotation_from_quat_xyzw(q, f"frames[{index}].pose.quat_render_from_cam_xyzw").as_matrix().T
        cam_from_render = _homogeneous(np.column_stack([Rt, -Rt @ t]))
        exr_cam = np.diag([1.0, -1.0, 1.0, 1.0]) @ cam_from_render
        hdr.update({"worldToCamera": np.ascontiguousarray(exr_cam.T, dtype=np.float32),
                    "renderlab:camFromRender": cam_from_render, "renderlab:position_m": t,
                    "renderlab:quat_render_from_cam_xyzw": json.dumps([float(v) for v in q]),
                    "renderlab:quat_convention": QUAT_CONVENTION})
    if all(k in (meta.get("camera") or {}) for k in ("fx", "fy", "cx", "cy")):
        hdr.update(_camera_attrs(meta["camera"], cam_from_render))
    return hdr


# ----------------------------------------------------------------------------------------- PNG
def _encode_png(a: np.ndarray, path) -> bytes:
    ok, buf = cv2.imencode(".png", a, list(PNG_PARAMS))
    if not ok:
        raise UserError(f"cannot encode PNG {path}")
    return buf.tobytes()


def _write_bytes(path, data: bytes) -> None:
    try:
        Path(path).write_bytes(data)
    except OSError as exc:
        raise UserError(f"cannot write PNG {path}: {exc.strerror or exc}") from None


def png_chunk(kind: bytes, data: bytes) -> bytes:
    """One PNG chunk: length, type, data, CRC-32 of type + data."""
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def with_sbit(png: bytes, bits: int) -> bytes:
    """Insert an ``sBIT`` chunk (``bits`` significant bits) right after the IHDR of a greyscale PNG."""
    if png[:8] != _PNG_SIGNATURE or png[12:16] != b"IHDR":
        raise ValueError("with_sbit: not a PNG that starts with IHDR")
    depth, colour = png[24], png[25]
    if colour != 0 or not 1 <= bits <= depth:
        raise ValueError(f"with_sbit: needs greyscale and 1 <= bits <= {depth}, got colour type "
                         f"{colour}, bits {bits}")
    end = 8 + 12 + struct.unpack(">I", png[8:12])[0]
    return png[:end] + png_chunk(b"sBIT", bytes([bits])) + png[end:]


def _check_dn(dn, bits: int) -> np.ndarray:
    a = np.asarray(dn)
    if a.ndim != 2 or not np.issubdtype(a.dtype, np.integer):
        raise ValueError(f"dn must be an integer (H, W) array, got {a.dtype} {a.shape}")
    if isinstance(bits, bool) or not isinstance(bits, (int, np.integer)) or not 1 <= bits <= 16:
        raise ValueError(f"dn bits must be an int in 1..16, got {bits!r}")
    if a.size and (a.min() < 0 or a.max() > 2 ** int(bits) - 1):
        raise ValueError(f"dn values must be in 0..{2 ** int(bits) - 1} ({bits} bits)")
    return np.ascontiguousarray(a, dtype=np.uint16)


def write_dn_png(path, dn: np.ndarray, bits: int = 16) -> None:
    """Write an integer (H, W) DN image as a 16-bit grayscale PNG with deterministic bytes.

    The N-bit values are stored as they are (not shifted); for ``bits`` < 16 an ``sBIT`` chunk
    records N so that viewers which honour it can scale the image.

    Parameters
    ----------
    path : str or os.PathLike
        Output file.
    dn : numpy.ndarray
        Integer (H, W) array with values in ``0 .. 2**bits - 1``.
    bits : int, optional
        Significant bits of the sensor (1..16).
    """
    a = _check_dn(dn, bits)
    png = _encode_png(a, path)
    _write_bytes(path, with_sbit(png, int(bits)) if bits < 16 else png)


def write_dn_preview(path, dn: np.ndarray, bits: int) -> None:
    """Write an 8-bit grey PNG preview of an N-bit DN image, linearly scaled: full scale
    ``2**bits - 1`` → 255 (rounded half up, integer arithmetic, so deterministic)."""
    a = _check_dn(dn, bits).astype(np.uint32)
    full = 2 ** int(bits) - 1
    _write_bytes(path, _encode_png(((a * 255 + full // 2) // full).astype(np.uint8), path))


def write_frame_files(folder: Path, rels: dict, channels: dict, header: dict, compression: str, dn: np.ndarray,
                      bits: int) -> None:
    """A truth-set frame's files under ``folder``: the EXR (``rels["exr"]``), and meanwhile, on a helper thread, the
    DN PNG (``rels["dn"]``) and its preview (``rels["dn_preview"]``) (in the writer's loop, thread or process). Both
    are done when it returns; the EXR's error comes first, then the PNGs'. OpenCV's encoder and OpenEXR's writer
    release the GIL, so on the 2-core machine the PNGs (0.15 s for a 1 MP frame) overlap the EXR."""
    folder = Path(folder)

    def pngs():
        write_dn_png(folder / rels["dn"], dn, bits)
        (folder / "dn_preview").mkdir(exist_ok=True)
        write_dn_preview(folder / rels["dn_preview"], dn, bits)

    with concurrent.futures.ThreadPoolExecutor(1, thread_name_prefix="renderlab-png") as pool:
        png_job = pool.submit(pngs)
        try:
            write_exr(folder / rels["exr"], channels, header, compression=compression)
        finally:
            concurrent.futures.wait([png_job])
        png_job.result()


def read_dn_png(path, size: tuple[int, int] | None = None) -> np.ndarray:
    """Read a 16-bit grayscale DN PNG as a uint16 (H, W) array (UserError if it is not one; with ``size`` =
    (width, height), the header must say that size before anything is decoded).

    The values come back exactly as stored; an ``sBIT`` chunk does not shift them."""
    p = Path(path)
    hdr = check_image(p, "PNG", size=size)
    if hdr.kind != "png":
        raise UserError(f"{shown(p)} is not a PNG")
    raw = np.frombuffer(read_bytes(p, "PNG", LIMITS["image"]), dtype=np.uint8)
    img = cv2.imdecode(raw, cv2.IMREAD_UNCHANGED) if raw.size else None
    if img is None:
        raise UserError(f"corrupt or unreadable PNG {shown(p)}")
    if img.dtype != np.uint16 or img.ndim != 2:
        raise UserError(f"PNG {shown(p)} is not 16-bit grayscale ({img.dtype}, shape {img.shape})")
    return img
