"""The inputs of tests/test_fuzz_files.py: a small lab of real files (a campaign, a published study, a truth set, a
landmark catalogue with an image and its a-priori file, a calibration file), each made by the lab's own writers or
the libraries' (pyarrow, OpenCV, OpenEXR), and the per-case changes the families (tests/fuzz_families.py) apply to
private copies of them (:func:`prepare`)."""

from __future__ import annotations

import json
import math
import os
import shutil
import struct
import zlib
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SCENE = REPO / "scenes" / "analytic_sphere_box.toml"
DELETE = "__delete__"
#: (placeholder, what it becomes in a case's argv): the shared lab, the case's private folder
LAB, CASE = "{LAB}", "{CASE}"
TINY_SUBS = [("width = 256", "width = 32"), ("height = 192", "height = 24"), ("fx = 262.0", "fx = 33.0"),
             ("fy = 258.0", "fy = 32.0"), ("cx = 131.3", "cx = 16.4"), ("cy = 93.8", "cy = 11.7"),
             ("frames = 4", "frames = 1"), ("spp = 16", "spp = 2")]
W, H = 32, 24  # the tiny camera


def tiny_scene_text() -> str:
    """scenes/analytic_sphere_box.toml at 32 × 24 px, 2 spp, one frame."""
    text = SCENE.read_text(encoding="utf-8")
    for old, new in TINY_SUBS:
        assert text.count(old) == 1, old
        text = text.replace(old, new)
    return text


# ------------------------------------------------------------------------------------------- the lab
def _catalog(d: Path) -> None:
    """A landmark catalogue folder: landmarks.parquet (two maplets) and maplets/NNNNNN.exr (15 × 15)."""
    import numpy as np
    import pyarrow as pa
    import pyarrow.parquet as pq

    from renderlab.files.imageio import write_exr

    (d / "maplets").mkdir(parents=True)
    ids = [1, 2]
    for i in ids:
        yy, xx = np.mgrid[-7:8, -7:8] * 0.1
        write_exr(d / "maplets" / f"{i:06d}.exr", {"height": 0.05 * np.cos(xx + i) * np.sin(yy),
                                                    "albedo": np.full((15, 15), 0.2 + 0.01 * i)})
    pq.write_table(pa.table({
        "landmark_id": pa.array(ids, pa.int64()), "center_x_m": [0.0, 0.5], "center_y_m": [0.0, -0.5],
        "center_z_m": [0.0, 0.0], "spacing_m": [0.1, 0.1], "size_px": pa.array([15, 15], pa.int64()),
        "q_body_from_maplet_x": [0.0, 0.0], "q_body_from_maplet_y": [0.0, 0.0], "q_body_from_maplet_z": [0.0, 0.0],
        "q_body_from_maplet_w": [1.0, 1.0], "maplet_file": [f"maplets/{i:06d}.exr" for i in ids]}),
        d / "landmarks.parquet")


def apriori_data() -> dict:
    """A valid a-priori file of one 32 × 24 image (docs/apriori_file.md)."""
    return {"camera": {"width": W, "height": H, "fx": 40.0, "fy": 40.0, "cx": 15.5, "cy": 11.5}, "bits": 12,
            "frame": "BODY",
            "images": [{"file": "img.png", "epoch_utc": "2024-06-21T10:00:00Z", "position_m": [0.0, 0.0, 5.0],
                        "quat_body_from_cam_xyzw": [1.0, 0.0, 0.0, 0.0], "sun_direction_body": [0.3, 0.2, 1.0],
                        "position_sigma_m": [0.1, 0.1, 0.1], "attitude_sigma_deg": [0.05, 0.05, 0.05]}]}


CALIBRATION = """%YAML:1.0
---
image_width: 32
image_height: 24
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 33.0, 0., 16.4, 0., 32.0, 11.7, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 1
   cols: 5
   dt: d
   data: [ 0.01, 0., 0., 0., 0. ]
"""


def build_lab(root: Path) -> None:
    """Every shared input of the families under ``root`` (made once; the cases never change it)."""
    import cv2
    import numpy as np

    from renderlab.campaign.publish import publish_campaign
    from renderlab.cli import main

    root.mkdir(parents=True, exist_ok=True)
    (root / "scene.toml").write_text(tiny_scene_text(), encoding="utf-8")
    quiet = ["--quiet"]
    assert main(["campaign", str(root / "scene.toml"), "--runs", "2", "--out", str(root / "camp"), "--workers", "0",
                 *quiet]) == 0
    shutil.rmtree(root / "camp" / "work")  # the truth cache: not read by report, publish or info
    publish_campaign(root / "camp", root / "pub")
    assert main(["render", str(root / "scene.toml"), "--out", str(root / "ts"), *quiet]) == 0
    _catalog(root / "cat")
    cv2.imwrite(str(root / "img.png"), (np.arange(W * H).reshape(H, W) * 5).astype(np.uint16))
    (root / "apriori.json").write_text(json.dumps(apriori_data(), indent=1), encoding="utf-8")
    (root / "calib.yaml").write_text(CALIBRATION, encoding="utf-8")
    (root / "plain.txt").write_text("a regular file\n")


# ------------------------------------------------------------------------------------------- crafted files
def png_header(width: int, height: int, depth: int = 16, colour: int = 0) -> bytes:
    """A PNG whose IHDR claims ``width`` × ``height`` and whose data is one tiny IDAT (a decompression bomb if
    decoded)."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    ihdr = struct.pack(">IIBBBBB", width, height, depth, colour, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"\0" * 64)) + chunk(b"IEND", b"")


def tiff_header(width: int, height: int) -> bytes:
    """A little-endian baseline TIFF whose first IFD claims ``width`` × ``height`` 16-bit grey pixels in one strip
    of 16 bytes."""
    entries = [(256, 4, 1, width), (257, 4, 1, height), (258, 3, 1, 16), (259, 3, 1, 1), (262, 3, 1, 1),
               (273, 4, 1, 8 + 2 + 12 * 9 + 4), (277, 3, 1, 1), (278, 4, 1, height), (279, 4, 1, 16)]
    ifd = struct.pack("<H", len(entries)) + b"".join(
        struct.pack("<HHII", tag, typ, n, val) if typ == 4 else struct.pack("<HHIHH", tag, typ, n, val, 0)
        for tag, typ, n, val in entries) + struct.pack("<I", 0)
    return b"II*\x00" + struct.pack("<I", 8) + ifd + b"\0" * 16


def fits_header(naxis1: int, naxis2: int, bitpix: int = 16, data_bytes: int = 2880) -> bytes:
    """A FITS primary HDU claiming ``naxis1`` × ``naxis2`` with only ``data_bytes`` of data after the header."""
    cards = [f"{'SIMPLE':<8}= {'T':>20}", f"{'BITPIX':<8}= {bitpix:>20}", f"{'NAXIS':<8}= {2:>20}",
             f"{'NAXIS1':<8}= {naxis1:>20}", f"{'NAXIS2':<8}= {naxis2:>20}", "END"]
    head = "".join(c.ljust(80) for c in cards).ljust(2880).encode("ascii")
    return head + b"\0" * data_bytes


def alias_bomb(width: int, depth: int) -> str:
    """A calibration YAML whose camera matrix is a list nested ``depth`` deep through aliases, each level naming
    the one below ``width`` times (``width ** depth`` nodes when expanded; a few hundred bytes on disk)."""
    lines = ["%YAML:1.0", "---", "l0: &l0 [1.0, 1.0]"]
    for k in range(1, depth + 1):
        lines.append(f"l{k}: &l{k} [{', '.join([f'*l{k - 1}'] * width)}]")
    lines.append(f"camera_matrix: *l{depth}")
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------------------------------- per-case setup
def _set_path(data, path: list, value):
    node = data
    for p in path[:-1]:
        node = node[p]
    if value == DELETE:
        del node[path[-1]]
    else:
        node[path[-1]] = value


def _json_value(v):
    """JSON-safe spelling of a case value (NaN and infinities as markers, restored in the child)."""
    if isinstance(v, float) and not math.isfinite(v):
        return {"__float__": repr(v)}
    return v


def _restore(v):
    if isinstance(v, dict) and set(v) == {"__float__"}:
        return float(v["__float__"])
    if isinstance(v, list):
        return [_restore(x) for x in v]
    if isinstance(v, dict):
        return {k: _restore(x) for k, x in v.items()}
    return v


def _special(path: Path, kind: str) -> None:
    """Put a special file at ``path``: FIFO, links to devices, a folder, a dangling link, a link loop."""
    if path.exists() or path.is_symlink():
        shutil.rmtree(path) if path.is_dir() and not path.is_symlink() else path.unlink()
    if kind == "fifo":
        os.mkfifo(path)
    elif kind in ("zero", "urandom", "null"):
        os.symlink(f"/dev/{kind}", path)
    elif kind == "folder":
        path.mkdir()
    elif kind == "dangling":
        os.symlink(path.name + ".nowhere", path)
    elif kind == "loop":
        os.symlink(path.name + ".b", path)
        os.symlink(path.name, path.with_name(path.name + ".b"))
    elif kind == "sparse":  # a file whose size is past every limit but one (hashing), with no data on disk
        with open(path, "wb") as fh:
            fh.truncate(3 << 30)
    else:
        raise KeyError(kind)


def _table(path: Path, op: str, arg) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    if op in ("truncate", "flip", "garbage"):
        data = path.read_bytes()
        if op == "truncate":
            data = data[:arg]
        elif op == "flip":
            data = bytearray(data)
            data[len(data) - arg] ^= 0xFF
            data = bytes(data)
        else:
            data = arg.encode()
        path.write_bytes(data)
        return
    t = pq.read_table(path)
    if op == "drop":
        t = t.drop_columns([arg])
    elif op == "retype":
        col = t.column(arg)
        if pa.types.is_string(col.type) or pa.types.is_dictionary(col.type):
            new = pa.array(list(range(t.num_rows)), pa.int64())
        else:
            new = pa.array([f"v{i}" for i in range(t.num_rows)], pa.string())
        t = t.set_column(t.column_names.index(arg), arg, new)
    elif op == "empty":
        t = t.slice(0, 0)
    elif op == "set_nan":  # the first row of a float column becomes NaN
        vals = t.column(arg).to_pylist()
        t = t.set_column(t.column_names.index(arg), arg, pa.array([math.nan, *vals[1:]], pa.float64()))
    elif op == "add_string_column":
        t = t.append_column(arg, pa.array(["x"] * t.num_rows, pa.string()))
    else:
        raise KeyError(op)
    pq.write_table(t, path)


def prepare(case_dir: Path, lab: Path, setup: list) -> None:
    """Apply a case's setup steps (JSON-able lists) in ``case_dir``: ``["copy", name]`` copies ``lab/name``;
    ``["json", file, path, value]`` changes one key (``DELETE`` removes it); ``["json_text", file, text]`` replaces
    the file; ``["table", file, op, arg]``; ``["special", file, kind]``; ``["text", file, text]``;
    ``["bytes_hex", file, hex]``."""
    case_dir.mkdir(parents=True, exist_ok=True)
    for step in setup:
        kind, *args = step
        if kind == "copy":
            src = lab / args[0]
            (shutil.copytree if src.is_dir() else shutil.copy2)(src, case_dir / args[0])
        elif kind == "json":
            f = case_dir / args[0]
            data = json.loads(f.read_text())
            _set_path(data, args[1], _restore(args[2]))
            f.write_text(json.dumps(data))
        elif kind in ("json_text", "text"):
            (case_dir / args[0]).write_text(args[1], encoding="utf-8")
        elif kind == "bytes_hex":
            (case_dir / args[0]).write_bytes(bytes.fromhex(args[1]))
        elif kind == "table":
            _table(case_dir / args[0], args[1], args[2])
        elif kind == "special":
            _special(case_dir / args[0], args[1])
        else:
            raise KeyError(kind)


# ------------------------------------------------------------------------------------------- the child
CASE_SECONDS = 30.0
PREFIX = "renderlab: error: "


class CaseTimeout(BaseException):
    """Raised by SIGALRM when a case runs past :data:`CASE_SECONDS` (not an Exception: nothing swallows it)."""


def families() -> dict:
    import fuzz_families
    import fuzz_families2

    return {"metadata": fuzz_families.metadata_cases, "tables": fuzz_families.tables_cases,
            "values": fuzz_families2.values_cases, "resources": fuzz_families2.resources_cases,
            "references": fuzz_families.references_cases, "outputs": fuzz_families.outputs_cases}


def _tree(root: Path) -> dict:
    out = {}
    for dirpath, dirnames, filenames in os.walk(root, followlinks=False):
        for name in dirnames + filenames:
            p = Path(dirpath) / name
            st = os.lstat(p)
            out[str(p.relative_to(root))] = (st.st_mode, st.st_size, st.st_mtime_ns)
    return out


_CALLED: list = []


def _sentinels() -> None:
    """Replace callables a reference case names with recorders: a case that calls one is caught."""
    import subprocess

    def recorder(name, real):
        def call(*a, **k):
            _CALLED.append(name)
            raise RuntimeError(f"{name} was called")
        call.__wrapped__ = real
        return call
    os.system = recorder("os.system", os.system)  # the lab never calls these in the commands under test
    subprocess.call = recorder("subprocess.call", subprocess.call)


def run_family(family: str, lab: Path, root: Path) -> None:
    """Run every case of ``family`` in this process (the child of tests/test_fuzz_files.py, under its memory cap):
    one JSON line per case in ``root/results.jsonl``."""
    import contextlib
    import io
    import signal
    import time

    os.environ["RENDERLAB_CACHE"] = str(root / "cache")
    import renderlab.cli as cli
    from renderlab.cli import main

    parser = cli.build_parser()  # one parser for every case: build_parser() makes the same parser on every call and
    cli.build_parser = lambda: parser  # parse_args leaves it as it was (the same results either way: every family)
    cases = families()[family](lab)
    _sentinels()

    def alarm(signum, frame):
        raise CaseTimeout()
    signal.signal(signal.SIGALRM, alarm)
    with open(root / "results.jsonl", "w", encoding="utf-8") as log:
        log.write(json.dumps({"cases": len(cases)}) + "\n")
        log.flush()
        for i, (cid, setup, argv, needle) in enumerate(cases):
            case_dir, work = root / "c" / str(i), root / "w" / str(i)
            prepare(case_dir, lab, setup)
            work.mkdir(parents=True)
            before = _tree(case_dir)
            argv = [a.replace(LAB, str(lab)).replace(CASE, str(case_dir)) for a in argv]
            out, err = io.StringIO(), io.StringIO()
            os.chdir(work)
            del _CALLED[:]
            t0 = time.perf_counter()
            signal.setitimer(signal.ITIMER_REAL, CASE_SECONDS)
            try:
                with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
                    rc = main(argv)
            except CaseTimeout:
                rc = "timeout"
            except BaseException as exc:  # noqa: BLE001 - reported, not hidden
                rc = f"raised {type(exc).__name__}: {str(exc)[:200]}"
            finally:
                signal.setitimer(signal.ITIMER_REAL, 0)
            seconds = time.perf_counter() - t0
            os.chdir(root)
            after = _tree(case_dir)
            changed = sorted(k for k in set(before) | set(after) if before.get(k) != after.get(k))
            lines = err.getvalue().splitlines()
            log.write(json.dumps({"id": cid, "rc": rc, "lines": len(lines), "line": lines[0] if lines else "",
                                  "longest": max((len(x) for x in lines), default=0), "needle": needle,
                                  "seconds": round(seconds, 3), "created": sorted(p.name for p in work.iterdir()),
                                  "changed": changed[:5], "called": list(_CALLED),
                                  "traceback": "Traceback" in err.getvalue() + out.getvalue()}) + "\n")
            log.flush()
            shutil.rmtree(case_dir, ignore_errors=True)
            shutil.rmtree(work, ignore_errors=True)
