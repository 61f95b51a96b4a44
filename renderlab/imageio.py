"""Image files of truth sets: float32 multi-channel EXR (OpenEXR package) and 16-bit PNG of DN.

EXR: single part, scanline, lossless ZIP, every channel float32, no timestamps in the header, so the
same data gives bit-identical bytes. PNG: 16-bit grey holding the N-bit DN values. A missing,
truncated or corrupt file raises :class:`UserError` naming it.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import OpenEXR

from renderlab.errors import UserError

_RESERVED_HEADER = {"channels", "compression", "dataWindow", "displayWindow", "lineOrder", "name",
                    "pixelAspectRatio", "screenWindowCenter", "screenWindowWidth", "type", "tiles",
                    "version", "chunkCount"}
_MAX_EXACT_ID = 2 ** 24  # float32 holds every integer of magnitude up to this exactly


# ----------------------------------------------------------------------------------- EXR / PNG
def write_exr(path, channels: dict, header_extra: dict | None = None) -> None:
    """Write a single-part scanline EXR, float32 channels, lossless ZIP compression.

    The header holds only the standard attributes plus ``header_extra`` (no time stamps), so
    the same data give bit-identical files.

    Parameters
    ----------
    path : str or os.PathLike
        Output file.
    channels : dict of str to numpy.ndarray
        Channel name → (H, W) real array (cast to float32; all the same shape).
    header_extra : dict of str to (str, int, float), optional
        Extra header attributes.
    """
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
        data[str(name)] = np.ascontiguousarray(a, dtype=np.float32)  # C order is required
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    for key, value in (header_extra or {}).items():
        if key in _RESERVED_HEADER or isinstance(value, bool) or not isinstance(
                value, (str, int, float)):
            raise ValueError(f"write_exr: header attribute {key!r}={value!r} not allowed")
        header[str(key)] = value
    try:
        with OpenEXR.File(header, data) as exr:
            exr.write(str(path))
    except (RuntimeError, OSError) as exc:
        raise UserError(f"cannot write EXR {path}: {exc}") from None


def read_exr(path) -> dict:
    """Read every channel of an EXR (part 0): ``{name: float32 (H, W) array}``.

    A missing, truncated or corrupt file raises :class:`UserError` naming the file.
    """
    p = Path(path)
    if not p.is_file():
        raise UserError(f"EXR file not found: {p}")
    try:
        with OpenEXR.File(str(p), separate_channels=True) as exr:
            out = {name: np.asarray(ch.pixels, dtype=np.float32)
                   for name, ch in exr.channels().items()}
    except (RuntimeError, OSError, ValueError) as exc:
        raise UserError(f"corrupt or unreadable EXR {p}: {exc}") from None
    if not out or any(a.ndim != 2 for a in out.values()):
        raise UserError(f"EXR {p} has no channels or non-2-D channels")
    return out


def write_dn_png(path, dn: np.ndarray) -> None:
    """Write an integer (H, W) DN image (values 0..65535, N-bit values stored as they are)
    as a 16-bit grayscale PNG with deterministic bytes."""
    a = np.asarray(dn)
    if a.ndim != 2 or not np.issubdtype(a.dtype, np.integer):
        raise ValueError(f"write_dn_png: dn must be an integer (H, W) array, got {a.dtype} "
                         f"{a.shape}")
    if a.size and (a.min() < 0 or a.max() > 65535):
        raise ValueError("write_dn_png: dn values must be in 0..65535")
    ok, buf = cv2.imencode(".png", np.ascontiguousarray(a, dtype=np.uint16),
                           [cv2.IMWRITE_PNG_COMPRESSION, 3])
    if not ok:
        raise UserError(f"cannot encode PNG {path}")
    try:
        Path(path).write_bytes(buf.tobytes())
    except OSError as exc:
        raise UserError(f"cannot write PNG {path}: {exc.strerror or exc}") from None


def read_dn_png(path) -> np.ndarray:
    """Read a 16-bit grayscale DN PNG as a uint16 (H, W) array (UserError if it is not one)."""
    p = Path(path)
    try:
        raw = np.frombuffer(p.read_bytes(), dtype=np.uint8)
    except OSError as exc:
        raise UserError(f"cannot read PNG {p}: {exc.strerror or exc}") from None
    img = cv2.imdecode(raw, cv2.IMREAD_UNCHANGED) if raw.size else None
    if img is None:
        raise UserError(f"corrupt or unreadable PNG {p}")
    if img.dtype != np.uint16 or img.ndim != 2:
        raise UserError(f"PNG {p} is not 16-bit grayscale ({img.dtype}, shape {img.shape})")
    return img
