"""A small reader and writer for CCSDS KVN (keyword = value notation), the subset OEM and AEM files use.

Structure read: the version line (``CCSDS_OEM_VERS = 2.0``), header keywords, then segments of
``META_START … META_STOP`` followed by data lines (OEM: bare; AEM: between ``DATA_START`` and ``DATA_STOP``).
``COMMENT`` lines and blank lines are skipped anywhere, as are OEM covariance blocks
(``COVARIANCE_START … COVARIANCE_STOP``). XML messages are not read.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from renderlab.errors import UserError


@dataclass
class Segment:
    """One META block and the data lines under it.

    Attributes
    ----------
    meta : dict of str to str
        META keywords (upper case) and their values (text, units in brackets removed).
    line : int
        Line number of ``META_START``.
    data : list of (int, list of str)
        Line number and whitespace-separated fields of each data line.
    """

    meta: dict[str, str]
    line: int
    data: list[tuple[int, list[str]]] = field(default_factory=list)


def _key_value(text: str, src: str, no: int) -> tuple[str, str]:
    if "=" not in text:
        raise UserError(f"{src} line {no}: expected KEYWORD = value, got {text[:60]!r}")
    key, value = text.split("=", 1)
    value = value.strip()
    if value.endswith("]") and "[" in value:  # "1.0 [km]": units in brackets
        value = value[: value.rindex("[")].strip()
    return key.strip().upper(), value


def read_kvn(path, kind: str) -> tuple[dict[str, str], list[Segment]]:
    """Parse a KVN ``OEM`` or ``AEM`` file into its header keywords and segments.

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    kind : {"OEM", "AEM"}
        The message type (checked against the version line).

    Raises
    ------
    UserError
        Missing file, not a KVN message of that kind, a line out of place.
    """
    path = Path(path)
    src = path.name
    if not path.is_file():
        raise UserError(f"CCSDS {kind} file not found: {path}")
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except UnicodeDecodeError:
        raise UserError(f"{src}: not a text file (CCSDS {kind} in KVN expected)") from None
    header: dict[str, str] = {}
    segments: list[Segment] = []
    state = "version"  # version → header → meta → data (→ covariance) → meta …
    in_data_block = kind != "AEM"
    for no, raw in enumerate(lines, start=1):
        text = raw.strip()
        if not text or text.upper().startswith("COMMENT"):
            continue
        word = text.split()[0].upper()
        if state == "version":
            key, value = _key_value(text, src, no) if "=" in text else (word, "")
            if key != f"CCSDS_{kind}_VERS":
                raise UserError(f"{src}: not a CCSDS {kind} in KVN (the first line must be "
                                f"CCSDS_{kind}_VERS = …, got {text[:40]!r})")
            header[key], state = value, "header"
        elif word == "META_START":
            if state == "meta":
                raise UserError(f"{src} line {no}: META_START inside a META block")
            segments.append(Segment({}, no))
            state, in_data_block = "meta", kind != "AEM"
        elif word == "META_STOP":
            if state != "meta":
                raise UserError(f"{src} line {no}: META_STOP without META_START")
            state = "data"
        elif state == "meta":
            key, value = _key_value(text, src, no)
            segments[-1].meta[key] = value
        elif state == "header":
            key, value = _key_value(text, src, no)
            header[key] = value
        elif word == "COVARIANCE_START":
            state = "covariance"
        elif word == "COVARIANCE_STOP":
            state = "data"
        elif state == "covariance":
            continue
        elif word in ("DATA_START", "DATA_STOP"):
            in_data_block = word == "DATA_START"
        elif in_data_block and "=" not in text:
            segments[-1].data.append((no, text.split()))
        else:
            raise UserError(f"{src} line {no}: unexpected {text[:60]!r}")
    if state == "version":
        raise UserError(f"{src}: empty file (CCSDS {kind} in KVN expected)")
    if not segments:
        raise UserError(f"{src}: no META_START … META_STOP segment")
    if state == "meta":
        raise UserError(f"{src}: META block opened at line {segments[-1].line} is not closed")
    return header, segments


def require(meta: dict[str, str], keys: tuple[str, ...], src: str, line: int) -> None:
    """UserError naming the first of ``keys`` missing from a META block."""
    for key in keys:
        if not meta.get(key):
            raise UserError(f"{src}: the META block at line {line} has no {key}")


def write_kvn(path, kind: str, version: str, header: dict[str, str], meta: dict[str, str], data: list[str],
              *, data_block: bool) -> None:
    """Write a one-segment KVN message (``data_block``: wrap data lines in DATA_START/DATA_STOP)."""
    width = max(len(k) for k in [*header, *meta, f"CCSDS_{kind}_VERS"])
    out = [f"{f'CCSDS_{kind}_VERS':<{width}} = {version}"]
    out += [f"{k:<{width}} = {v}" for k, v in header.items()]
    out += ["", "META_START", *[f"{k:<{width}} = {v}" for k, v in meta.items()], "META_STOP", ""]
    out += (["DATA_START", *data, "DATA_STOP"] if data_block else data)
    Path(path).write_text("\n".join(out) + "\n", encoding="utf-8")
