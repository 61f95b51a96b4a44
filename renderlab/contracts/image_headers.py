"""Image headers read before any pixel is decoded: PNG, TIFF, FITS and EXR sizes checked against the lab's limits
and, where the image belongs to a camera, against the camera.

A decoder allocates what the header claims (a 200-byte PNG can claim 65535 × 65535 pixels, a FITS header any
NAXIS), so every image the lab reads — albedo maps, ``measure --images`` images, a truth set's EXR and DN PNG — is
first opened as a regular file of bounded size (:func:`renderlab.inputs.open_regular`), its header parsed
here (PNG's IHDR and FITS cards by hand; TIFF and other formats through Pillow's lazy open, which reads the header
only; EXR through OpenEXR's ``header_only``), and its size compared with :data:`MAX_SIDE_PX` /
:data:`MAX_PIXELS`, with the file's own size (a FITS data unit longer than the file) and with the expected size.
"""

from __future__ import annotations

import os
import struct
from dataclasses import dataclass
from pathlib import Path

from renderlab.errors import UserError
from renderlab.inputs import LIMITS, open_regular, shown

#: the longest image side the lab decodes, px
MAX_SIDE_PX = 65_535
#: the most pixels of one image the lab decodes (e.g. 16384 × 8192)
MAX_PIXELS = 1 << 27
_PNG = b"\x89PNG\r\n\x1a\n"
_FITS_BLOCK = 2880
_FITS_SUFFIXES = (".fits", ".fit", ".fts")
_MAX_FITS_HDUS = 64


@dataclass(frozen=True)
class ImageHeader:
    """What a header says: ``width``, ``height`` (px), ``channels``, ``kind`` (``png``, ``tiff``, ``fits``, ``exr``,
    or Pillow's format name) and, for FITS, the index of the first 2-D image HDU."""

    width: int
    height: int
    channels: int
    kind: str
    hdu: int = 0


def _png(head: bytes, where: str) -> ImageHeader:
    if len(head) < 33 or head[12:16] != b"IHDR":
        raise UserError(f"{where}: a PNG without its IHDR header")
    w, h, depth, colour = struct.unpack(">IIBB", head[16:26])
    channels = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}.get(colour)
    if channels is None or depth not in (1, 2, 4, 8, 16):
        raise UserError(f"{where}: a PNG with colour type {colour} and bit depth {depth}")
    return ImageHeader(w, h, channels, "png")


def _fits_cards(fh, where: str) -> dict:
    """The cards of one FITS header (up to END) as {keyword: value text}."""
    cards: dict[str, str] = {}
    for _ in range(1000):  # 1000 blocks of 36 cards
        block = fh.read(_FITS_BLOCK)
        if len(block) < _FITS_BLOCK:
            raise UserError(f"{where}: a FITS header that ends before its END card")
        for i in range(0, _FITS_BLOCK, 80):
            card = block[i:i + 80].decode("ascii", "replace")
            key = card[:8].strip()
            if key == "END":
                return cards
            if card[8:10] == "= ":
                cards.setdefault(key, card[10:].split("/")[0].strip())
    raise UserError(f"{where}: a FITS header without an END card")


def _fits_int(cards: dict, key: str, where: str) -> int:
    try:
        return int(cards[key])
    except (KeyError, ValueError):
        raise UserError(f"{where}: FITS header card {key} is missing or not an integer") from None


def _fits(fh, size: int, where: str) -> ImageHeader:
    pos = 0
    for hdu in range(_MAX_FITS_HDUS):
        fh.seek(pos)
        cards = _fits_cards(fh, where)
        header_end = fh.tell()
        bitpix = _fits_int(cards, "BITPIX", where)
        naxis = _fits_int(cards, "NAXIS", where)
        if bitpix not in (8, 16, 32, 64, -32, -64) or not 0 <= naxis <= 999:
            raise UserError(f"{where}: FITS header with BITPIX {bitpix}, NAXIS {naxis}")
        dims = [_fits_int(cards, f"NAXIS{i + 1}", where) for i in range(naxis)]
        if any(d < 0 or d > 1 << 40 for d in dims):
            raise UserError(f"{where}: FITS axis lengths {dims[:4]} out of range")
        n = 1
        for d in dims:
            n *= d
        pcount = int(cards.get("PCOUNT", "0")) if cards.get("PCOUNT", "0").lstrip("-").isdigit() else 0
        nbytes = (abs(bitpix) // 8) * (n if naxis else 0) + max(pcount, 0)
        if header_end + nbytes > size:
            raise UserError(f"{where}: the FITS header claims {nbytes} bytes of data, more than the file holds")
        image = hdu == 0 or cards.get("XTENSION", "").strip("' ") == "IMAGE"
        if image and naxis == 2 and n > 0:
            return ImageHeader(dims[0], dims[1], 1, "fits", hdu)
        pos = header_end + -(-nbytes // _FITS_BLOCK) * _FITS_BLOCK
        if pos >= size:
            break
    raise UserError(f"{where}: no 2-D image HDU")


def _exr(path: Path, where: str) -> ImageHeader:
    import OpenEXR

    try:
        with OpenEXR.File(str(path), header_only=True) as f:
            head = f.header()
            lo, hi = head["dataWindow"]
            channels = len(f.channels())
    except Exception as exc:  # noqa: BLE001 - any header the library refuses
        raise UserError(f"{where}: not a readable EXR ({' '.join(str(exc).split())[:100]})") from None
    return ImageHeader(int(hi[0]) - int(lo[0]) + 1, int(hi[1]) - int(lo[1]) + 1, max(channels, 1), "exr")


def _pillow(fh, where: str) -> ImageHeader:
    from PIL import Image

    Image.MAX_IMAGE_PIXELS = None  # the size is checked below, against the lab's own limit
    try:
        with Image.open(fh) as im:
            w, h = im.size
            return ImageHeader(int(w), int(h), len(im.getbands()), str(im.format or "image").lower())
    except Exception as exc:  # noqa: BLE001 - Pillow raises many kinds for what it cannot identify
        raise UserError(f"{where}: not an image the lab reads ({type(exc).__name__})") from None


def image_header(path, what: str, *, limit: int = LIMITS["image"]) -> ImageHeader:
    """The header of the image file ``path`` (a regular file of at most ``limit`` bytes), sizes checked against
    :data:`MAX_SIDE_PX` and :data:`MAX_PIXELS`; UserError naming ``what`` otherwise."""
    p = Path(path)
    fd, size = open_regular(p, what, limit)
    where = f"{what} {shown(p)}"
    with os.fdopen(fd, "rb") as fh:
        head = fh.read(64)
        if head.startswith(_PNG):
            hdr = _png(head, where)
        elif head.startswith(b"SIMPLE  =") or p.suffix.lower() in _FITS_SUFFIXES:
            hdr = _fits(fh, size, where)
        elif head.startswith(b"\x76\x2f\x31\x01"):  # OpenEXR magic
            hdr = _exr(p, where)
        else:
            fh.seek(0)
            hdr = _pillow(fh, where)
    if not (1 <= hdr.width <= MAX_SIDE_PX and 1 <= hdr.height <= MAX_SIDE_PX) or hdr.width * hdr.height > MAX_PIXELS:
        raise UserError(f"{where}: the header says {hdr.width} × {hdr.height} px; the lab decodes at most "
                        f"{MAX_SIDE_PX} px a side and {MAX_PIXELS} pixels")
    return hdr


def check_image(path, what: str, *, size: tuple[int, int] | None = None, limit: int = LIMITS["image"]) -> ImageHeader:
    """:func:`image_header`, and (``size`` = (width, height)) the image must be that size (the camera's)."""
    hdr = image_header(path, what, limit=limit)
    if size is not None and (hdr.width, hdr.height) != tuple(size):
        raise UserError(f"{what} {shown(path)} is {hdr.width} × {hdr.height} px, but the camera is "
                        f"{size[0]} × {size[1]} px")
    return hdr
