"""What the lab is given, read with bounds: regular files of a sane size, JSON and YAML parsed with limits, values
validated by a pydantic model and quoted in error messages by a short prefix only; the epoch range every reader
shares.

The lowest layer but :mod:`renderlab.errors` (every reader, down to :mod:`renderlab.geometry`, uses it).

Every file the lab reads (metadata JSON, calibration YAML, albedo maps, images, meshes, tables) goes through
:func:`open_regular` or one of the readers built on it:

* only a regular file is opened (a symlink is followed to its target): a FIFO, a device (``/dev/zero``), a socket
  or a folder is refused before a byte is read, so nothing can block or stream forever;
* its size is checked against the kind's limit (:data:`LIMITS`) before it is read or hashed, and the read itself
  stops at the limit (a file that grows, or a ``/proc`` file that reports size 0);
* JSON nested deeper than Python's parser copes with, YAML with more nodes than :data:`MAX_YAML_NODES` once its
  aliases are expanded (an "alias bomb": a 1 KB file naming a list of lists a billion times), invalid UTF-8 and
  the like are one-line :class:`~renderlab.errors.UserError`\\ s naming the file.

:func:`short` is how an error message quotes a user's value: a bounded ``repr`` (``reprlib``: a few items per
level, a few levels, a short prefix of each string) cut to :data:`QUOTE_CHARS` characters, cheap however large or
self-referencing the value is. :func:`validate` checks data against a model (:mod:`renderlab.contracts.file_models`)
and reports the first problem as ``<where>: <key path>: <what> (got <short value>)``. :func:`check_epoch_text`
keeps epochs inside :data:`EPOCH_YEARS`, where the lab's time scales (leap seconds, Earth orientation, ephemerides)
are defined.
"""

from __future__ import annotations

import json
import os
import re
import reprlib
import stat
from pathlib import Path
from typing import Any

from renderlab.errors import UserError

MiB = 1 << 20
#: file kind → the largest file the lab reads of that kind, bytes
LIMITS = {"json": 256 * MiB, "calibration": 4 * MiB, "image": 1024 * MiB, "mesh": 1024 * MiB, "table": 2048 * MiB,
          "text": 16 * MiB, "trajectory": 1024 * MiB,
          "hashed": 64 * 1024 * MiB}  # streamed through a hash (SPICE kernels can be GB)
#: the most nodes a YAML document may hold with its aliases expanded
MAX_YAML_NODES = 100_000
#: characters of a user value an error message quotes at most
QUOTE_CHARS = 60
_READ_BLOCK = 1 << 20
#: the largest |focal length|, |principal point| or |skew| the lab takes, px (a 2 m focal length on 1 µm pixels is
#: 2e6 px; past this a camera is a typo, and products of intrinsics overflow)
PIXEL_MAX = 1e7
#: the largest |distortion coefficient| the lab takes
COEFF_MAX = 1e6
#: calendar years of the epochs the lab's time scales support: UTC exists from 1960 (ERFA's leap-second table starts
#: there), and ERFA's Earth ephemeris ``epv00`` and precession-nutation are stated for 1900-2100
EPOCH_YEARS = (1960, 2100)
_EPOCH = re.compile(r"^\s*([+-]?\d{1,9})-")

_repr = reprlib.Repr()
_repr.maxlevel, _repr.maxtuple, _repr.maxlist, _repr.maxarray, _repr.maxdict = 3, 4, 4, 4, 4
_repr.maxset, _repr.maxfrozenset, _repr.maxdeque = 4, 4, 4
_repr.maxstring, _repr.maxlong, _repr.maxother = QUOTE_CHARS, 24, QUOTE_CHARS


def short(value: Any, limit: int = QUOTE_CHARS) -> str:
    """A bounded ``repr`` of ``value`` (at most ``limit`` characters; ``…`` marks a cut), cheap for any value."""
    try:
        text = _repr.repr(value)
    except Exception:  # noqa: BLE001 - a value whose repr fails: its type
        text = f"<{type(value).__name__}>"
    text = " ".join(text.split())
    return text if len(text) <= limit else text[:limit - 1] + "…"


def shown(path: Any) -> str:
    """A path as error messages show it: its text, cut to 160 characters (the end kept: the file name)."""
    text = " ".join(os.fsdecode(path).split()) if isinstance(path, (str, bytes, os.PathLike)) else short(path)
    return text if len(text) <= 160 else "…" + text[-159:]


def _kind_of(mode: int) -> str:
    for test, word in ((stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
                       (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
                       (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return word
    return "not a regular file"


def _size_text(n: int) -> str:
    return f"{n / MiB:.0f} MiB" if n >= MiB else f"{n} bytes"


def open_regular(path, what: str, limit: int) -> tuple[int, int]:
    """Open ``path`` for reading if it is a regular file of at most ``limit`` bytes: ``(fd, size)``; the caller
    closes ``fd``. Opening never blocks (``O_NONBLOCK``: a FIFO is refused, not waited on).

    Raises
    ------
    UserError
        Missing, unreadable, not a regular file (folder, FIFO, device, socket) or larger than ``limit``.
    """
    p = os.fspath(path)
    try:
        fd = os.open(p, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise UserError(f"{what} not found: {shown(p)}") from None
    except OSError as exc:
        raise UserError(f"cannot open {what} {shown(p)}: {exc.strerror or type(exc).__name__}") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise UserError(f"{what} {shown(p)} is {_kind_of(st.st_mode)}; a regular file is needed")
        if st.st_size > limit:
            raise UserError(f"{what} {shown(p)} is {_size_text(st.st_size)}, more than the {_size_text(limit)} the "
                            f"lab reads")
        os.set_blocking(fd, True)
    except BaseException:
        os.close(fd)
        raise
    return fd, st.st_size


def check_regular(path, what: str, limit: int) -> int:
    """The size of ``path`` when it is a regular file of at most ``limit`` bytes (:func:`open_regular`)."""
    fd, size = open_regular(path, what, limit)
    os.close(fd)
    return size


def read_bytes(path, what: str, limit: int) -> bytes:
    """The content of a regular file of at most ``limit`` bytes (:func:`open_regular`); the read stops at the
    limit, so a file that grows meanwhile (or a ``/proc`` file, whose size reads 0) cannot exceed it."""
    fd, _ = open_regular(path, what, limit)
    parts, total = [], 0
    try:
        while True:
            block = os.read(fd, _READ_BLOCK)
            if not block:
                break
            total += len(block)
            if total > limit:
                raise UserError(f"{what} {shown(path)} is more than the {_size_text(limit)} the lab reads")
            parts.append(block)
    except OSError as exc:
        raise UserError(f"cannot read {what} {shown(path)}: {exc.strerror or type(exc).__name__}") from None
    finally:
        os.close(fd)
    return b"".join(parts)


def read_text(path, what: str, limit: int) -> str:
    """UTF-8 text of a regular file (:func:`read_bytes`); a byte-order mark is dropped."""
    data = read_bytes(path, what, limit)
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise UserError(f"{what} {shown(path)} is not UTF-8 text (byte {exc.start})") from None


def sha256(path, what: str, limit: int) -> str:
    """``sha256:<hex>`` of a regular file of at most ``limit`` bytes, read in blocks (:func:`open_regular`)."""
    import hashlib

    fd, _ = open_regular(path, what, limit)
    h, total = hashlib.sha256(), 0
    try:
        while True:
            block = os.read(fd, _READ_BLOCK)
            if not block:
                break
            total += len(block)
            if total > limit:
                raise UserError(f"{what} {shown(path)} is more than the {_size_text(limit)} the lab reads")
            h.update(block)
    except OSError as exc:
        raise UserError(f"cannot read {what} {shown(path)}: {exc.strerror or type(exc).__name__}") from None
    finally:
        os.close(fd)
    return "sha256:" + h.hexdigest()


def parse_json(text: str, where: str) -> Any:
    """``json.loads`` with one-line errors (syntax, nesting too deep)."""
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise UserError(f"cannot read {where}: not valid JSON ({exc.msg} at line {exc.lineno} column {exc.colno})") \
            from None
    except RecursionError:
        raise UserError(f"cannot read {where}: JSON nested too deeply") from None


def read_json(path, what: str, limit: int = LIMITS["json"]) -> Any:
    """The JSON value of a regular file (:func:`read_text`, :func:`parse_json`)."""
    return parse_json(read_text(path, what, limit), f"{what} {shown(path)}")


def _loc(loc) -> str:
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


def validation_message(exc, where: str) -> str:
    """The first error of a pydantic ``ValidationError`` as one line, the offending value quoted by :func:`short`."""
    errors = exc.errors(include_url=False, include_context=False, include_input=True)
    if not errors:
        return f"{where}: invalid"
    e = min(errors, key=lambda x: x.get("type") == "missing")  # a wrong value says more than a missing key
    loc = _loc(e.get("loc", ()))
    msg = e.get("msg", "invalid")
    if e.get("type") == "missing":
        return f"{where}: {loc or 'value'}: missing"
    if e.get("type") == "extra_forbidden":
        return f"{where}: unknown key {short(str(e.get('loc', ('?',))[-1]))}"
    msg = msg.replace("Input should be", "must be").replace("Value error, ", "")
    got = "" if e.get("input") is None else f" (got {short(e.get('input'))})"
    more = f"; {len(errors) - 1} more problem{'s' if len(errors) > 2 else ''}" if len(errors) > 1 else ""
    return f"{where}: {loc + ': ' if loc else ''}{msg}{got}{more}"


def validate(model, data: Any, where: str):
    """``model.model_validate(data)`` (or a TypeAdapter's), a ``ValidationError`` becoming one UserError line."""
    from pydantic import ValidationError

    try:
        if hasattr(model, "validate_python"):  # a TypeAdapter
            return model.validate_python(data)
        return model.model_validate(data)
    except ValidationError as exc:
        raise UserError(validation_message(exc, where)) from None
    except RecursionError:
        raise UserError(f"{where}: nested too deeply") from None


def read_model(path, model, what: str, limit: int = LIMITS["json"]):
    """A JSON file validated by ``model`` (:func:`read_json`, :func:`validate`): the model."""
    return validate(model, read_json(path, what, limit), f"{what} {shown(path)}")


def read_checked(path, model, what: str, limit: int = LIMITS["json"]) -> Any:
    """A JSON file validated by ``model``: the data as parsed (validated, nothing added or converted)."""
    data = read_json(path, what, limit)
    validate(model, data, f"{what} {shown(path)}")
    return data


def yaml_nodes(node, limit: int = MAX_YAML_NODES) -> int:
    """Nodes of a composed YAML graph with every alias expanded (memoised: linear in the distinct nodes), stopping
    once past ``limit``."""
    import yaml

    sizes: dict[int, int] = {}
    active: set[int] = set()

    def size(n) -> int:
        key = id(n)
        if key in sizes:
            return sizes[key]
        if key in active:  # a node that contains itself: infinite when expanded
            return limit + 1
        active.add(key)
        total = 1
        if isinstance(n, yaml.SequenceNode):
            for child in n.value:
                total += size(child)
                if total > limit:
                    break
        elif isinstance(n, yaml.MappingNode):
            for k, v in n.value:
                total += size(k) + size(v)
                if total > limit:
                    break
        active.discard(key)
        sizes[key] = total
        return total
    return size(node)


def load_yaml(text: str, loader, where: str) -> Any:
    """One YAML document with ``loader`` (a ``yaml.SafeLoader`` subclass), refused when its aliases expand past
    :data:`MAX_YAML_NODES` nodes (checked on the composed graph, before anything is built from it)."""
    import yaml

    try:
        ld = loader(text)
        try:
            node = ld.get_single_node()
            if node is None:
                return None
            n = yaml_nodes(node)
            if n > MAX_YAML_NODES:
                raise UserError(f"{where}: YAML expands to more than {MAX_YAML_NODES} nodes through its aliases "
                                "(an alias bomb?)")
            return ld.construct_document(node)
        finally:
            ld.dispose()
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        at = f" at line {mark.line + 1}" if mark is not None else ""
        raise UserError(f"{where}: not valid YAML ({short(getattr(err, 'problem', None) or 'parse error', 80)}"
                        f"{at})") from None
    except RecursionError:
        raise UserError(f"{where}: YAML nested too deeply") from None


def ensure_path_text(value: Any, what: str) -> Path:
    """A file name given in a data file as a Path: a non-empty string without NUL."""
    if not isinstance(value, str) or not value or "\x00" in value:
        raise UserError(f"{what} must be a file name, got {short(value)}")
    return Path(value)


def check_epoch_text(text: str) -> str:
    """An ISO epoch's year must lie in :data:`EPOCH_YEARS` (ValueError otherwise)."""
    m = _EPOCH.match(text)
    if m is None:
        raise ValueError("an ISO epoch YYYY-MM-DDThh:mm:ss is needed")
    year = int(m[1])
    if not EPOCH_YEARS[0] <= year <= EPOCH_YEARS[1]:
        raise ValueError(f"year {year} is outside the supported {EPOCH_YEARS[0]}..{EPOCH_YEARS[1]}")
    return text


def epoch_text(value: Any, what: str) -> str:
    """An epoch given as text (at most 64 characters, year inside :data:`EPOCH_YEARS`), else one UserError line."""
    if not isinstance(value, str) or len(value) > 64:
        raise UserError(f"{what} must be an ISO epoch, got {short(value)}")
    try:
        return check_epoch_text(value)
    except ValueError as exc:
        raise UserError(f"{what} {short(value)}: {exc}") from None
