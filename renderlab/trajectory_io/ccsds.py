"""CCSDS Orbit and Attitude Ephemeris Messages (OEM 502.0, AEM 504.0) in KVN: read and write.

Versions, from the ``CCSDS_OEM_VERS`` / ``CCSDS_AEM_VERS`` line: OEM 1.0, 2.0 and 3.0 (502.0-B-1, -B-2, -B-3: the
same META keywords and data lines for what the lab reads) and AEM 1.0 (ADM 504.0-B-1) and 2.0 (504.0-B-2); any
other version is refused by its number. ADM 2.0 differs from 1.0 in what the lab reads by (504.0-B-2 §4 and its
annex of changes): no ``ATTITUDE_DIR`` (the rotation is always A2B; a ``B2A`` is refused), no ``QUATERNION_TYPE``
(the data line is ``Q1 Q2 Q3 QC``, scalar last; an explicit ``QUATERNION_TYPE`` is honoured), and
``QUATERNION/ANGVEL`` (quaternion + 3 angular rates) instead of ``QUATERNION/RATE``. The ``ccsds-ndm`` package
(3.1) writes AEM 2.0 quaternions scalar first with a lower-case ``ATTITUDE_TYPE = quaternion``: such a file
(lower-case type, no ``QUATERNION_TYPE``) is refused with a line asking for ``QUATERNION_TYPE``, rather than read
with the components shifted.

Read subset. META: ``OBJECT_NAME``, ``CENTER_NAME``, ``REF_FRAME`` (OEM), ``REF_FRAME_A``/``REF_FRAME_B``,
``ATTITUDE_DIR`` (``A2B``/``B2A``), ``ATTITUDE_TYPE`` (``QUATERNION``, ``QUATERNION/DERIVATIVE``,
``QUATERNION/RATE``; only the quaternion is used), ``QUATERNION_TYPE`` (``FIRST``/``LAST``) (AEM),
``TIME_SYSTEM`` (UTC, TAI, TT, TDB). OEM data lines: epoch, x y z (km), vx vy vz (km/s), optional
accelerations (ignored). Segments are joined in order (a repeated boundary epoch is dropped) and must share
object, centre, frames and time system. ``USEABLE_START_TIME``/``USEABLE_STOP_TIME`` and ``INTERPOLATION`` are
not enforced: the lab interpolates as :mod:`renderlab.trajectory_io.series` says.

Quaternion convention: an ``X2Y`` quaternion, read by scipy ``Rotation.from_quat`` (scalar last), maps
Y-frame coordinates to X-frame coordinates (``R_X_from_Y``; the CCSDS direction-cosine matrix of the quaternion
is its transpose, the X→Y coordinate transformation). So with ``REF_FRAME_A`` the trajectory frame and
``REF_FRAME_B`` the camera, an ``A2B`` quaternion is ``R_frame_from_cam`` itself.
"""

from __future__ import annotations

from datetime import datetime, timezone
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from renderlab.errors import UserError
from renderlab.trajectory_io.kvn import read_kvn, require, write_kvn
from renderlab.trajectory_io.series import PoseSeries
from renderlab.trajectory_io.timescales import Epoch, parse_epoch

#: frame names that mean the same axes (CCSDS spells J2000 EME2000)
FRAME_ALIASES = {"EME2000": "J2000"}
QUAT_TYPES = ("QUATERNION", "QUATERNION/DERIVATIVE", "QUATERNION/RATE")
#: versions read → their standard; ADM 2.0's quaternion types (QUATERNION/RATE is 1.0 only) and data line widths
OEM_VERSIONS = {"1.0": "502.0-B-1", "2.0": "502.0-B-2", "3.0": "502.0-B-3"}
AEM_VERSIONS = {"1.0": "504.0-B-1", "2.0": "504.0-B-2"}
QUAT_TYPES_V2 = ("QUATERNION", "QUATERNION/DERIVATIVE", "QUATERNION/ANGVEL")
_WIDTH = {"QUATERNION": 4, "QUATERNION/DERIVATIVE": 8, "QUATERNION/RATE": 7, "QUATERNION/ANGVEL": 7}


def message_version(header: dict[str, str], kind: str, src: str) -> str:
    """The message's version (``"1.0"``...) from its ``CCSDS_<kind>_VERS`` line, refused unless the lab reads it."""
    known = OEM_VERSIONS if kind == "OEM" else AEM_VERSIONS
    raw = header.get(f"CCSDS_{kind}_VERS", "")
    try:
        version = f"{float(raw):.1f}"
    except ValueError:
        version = None
    if version not in known:
        names = ", ".join(f"{v} ({std})" for v, std in known.items())
        raise UserError(f"{src}: CCSDS_{kind}_VERS = {raw or '(empty)'} is not a version this lab reads ({kind} {names})")
    return version


def same_frame(a: str | None, b: str | None) -> bool:
    """Whether two frame names mean the same frame (case and the EME2000/J2000 alias ignored)."""
    norm = [FRAME_ALIASES.get(str(x).strip().upper(), str(x).strip().upper()) for x in (a, b)]
    return norm[0] == norm[1]


def _shared(segments, keys: tuple[str, ...], src: str) -> dict[str, str]:
    first = segments[0].meta
    for seg in segments[1:]:
        for key in keys:
            if seg.meta.get(key, "").upper() != first.get(key, "").upper():
                raise UserError(f"{src}: segment at line {seg.line} has {key} {seg.meta.get(key)!r}, the first "
                                f"has {first.get(key)!r} (one object, centre, frame and time system per file)")
    return first


def _epochs_values(segments, width: tuple[int, ...], src: str, what: str):
    """(epochs, values (n, max width), labels) of all segments' data lines, boundary repeats dropped."""
    epochs, rows, labels = [], [], []
    for seg in segments:
        system = seg.meta["TIME_SYSTEM"].upper()
        if not seg.data:
            raise UserError(f"{src}: the segment at line {seg.line} has no data lines")
        for no, fields in seg.data:
            if len(fields) - 1 not in width:
                raise UserError(f"{src} line {no}: an {what} data line needs an epoch and "
                                f"{' or '.join(map(str, width))} numbers, got {len(fields) - 1}")
            ep = parse_epoch(fields[0], system, f"{src} line {no}")
            try:
                vals = [float(v) for v in fields[1:]]
            except ValueError:
                raise UserError(f"{src} line {no}: not a number in {' '.join(fields[1:])!r}") from None
            if epochs and no == seg.data[0][0] and ep.minus(epochs[-1]) == 0.0:
                continue  # a segment starting where the previous one stopped
            epochs.append(ep)
            rows.append(vals + [0.0] * (max(width) - len(vals)))
            labels.append(f"line {no}")
    return epochs, np.array(rows, float), tuple(labels)


def read_oem(path) -> PoseSeries:
    """Positions (m) and velocities (m/s) of a KVN OEM (module docstring), in its ``REF_FRAME``."""
    header, segments = read_kvn(path, "OEM")
    src = Path(path).name
    message_version(header, "OEM", src)
    for seg in segments:
        require(seg.meta, ("OBJECT_NAME", "CENTER_NAME", "REF_FRAME", "TIME_SYSTEM"), src, seg.line)
    meta = _shared(segments, ("OBJECT_NAME", "CENTER_NAME", "REF_FRAME", "TIME_SYSTEM"), src)
    epochs, vals, labels = _epochs_values(segments, (6, 9), src, "OEM")
    return PoseSeries(times_s=np.array([e.minus(epochs[0]) for e in epochs]), positions_m=vals[:, 0:3] * 1e3,
                      quat_xyzw=None, frame=meta["REF_FRAME"], epoch0=epochs[0], velocities_m_s=vals[:, 3:6] * 1e3,
                      source=src, object_name=meta["OBJECT_NAME"], center_name=meta["CENTER_NAME"], labels=labels)


def _quaternion_type(meta: dict[str, str], v2: bool, src: str) -> str:
    """``FIRST`` or ``LAST``: the file's ``QUATERNION_TYPE``, else ADM 2.0's scalar last (module docstring)."""
    given = meta.get("QUATERNION_TYPE")
    if given is None:
        raw = meta["ATTITUDE_TYPE"]
        if raw.upper().startswith("QUATERNION") and raw != raw.upper():
            raise UserError(f"{src}: ATTITUDE_TYPE = {raw} in lower case is how ccsds-ndm 3.1 writes AEM 2.0, with the "
                            "quaternion scalar first (QC Q1 Q2 Q3) where 504.0-B-2 puts it last (Q1 Q2 Q3 QC); add "
                            "QUATERNION_TYPE = FIRST (or LAST) to the META block to say which")
        return "LAST"
    if given.upper() not in ("FIRST", "LAST"):
        raise UserError(f"{src}: QUATERNION_TYPE must be FIRST or LAST, got {given!r}")
    return given.upper()


def read_aem(path, frame: str | None = None) -> PoseSeries:
    """Attitude of a KVN AEM as ``R_frame_from_cam`` quaternions (module docstring).

    Parameters
    ----------
    path : str or os.PathLike
        The AEM file.
    frame : str, optional
        The trajectory's reference frame: must be ``REF_FRAME_A`` or ``REF_FRAME_B`` (the other one is the
        camera's). Default: ``REF_FRAME_A``.

    Raises
    ------
    UserError
        Missing keywords, unsupported attitude or time type, neither frame being ``frame``, bad data lines.
    """
    header, segments = read_kvn(path, "AEM")
    src = Path(path).name
    v2 = message_version(header, "AEM", src) == "2.0"
    keys = ("OBJECT_NAME", "REF_FRAME_A", "REF_FRAME_B", "TIME_SYSTEM", "ATTITUDE_TYPE")
    for seg in segments:
        require(seg.meta, keys if v2 else (*keys, "ATTITUDE_DIR", "QUATERNION_TYPE"), src, seg.line)
    meta = _shared(segments, (*keys, "ATTITUDE_DIR", "QUATERNION_TYPE"), src)
    a, b = meta["REF_FRAME_A"], meta["REF_FRAME_B"]
    direction, att_type = meta.get("ATTITUDE_DIR", "A2B").upper(), meta["ATTITUDE_TYPE"].upper()
    if direction not in ("A2B", "B2A"):
        raise UserError(f"{src}: ATTITUDE_DIR must be A2B or B2A, got {meta['ATTITUDE_DIR']!r}")
    if v2 and direction != "A2B":
        raise UserError(f"{src}: CCSDS_AEM_VERS 2.0 rotates from REF_FRAME_A to REF_FRAME_B; ATTITUDE_DIR = "
                        f"{meta['ATTITUDE_DIR']} is ADM 1.0 only (504.0-B-2)")
    types = QUAT_TYPES_V2 if v2 else QUAT_TYPES
    if att_type not in types:
        raise UserError(f"{src}: ATTITUDE_TYPE {meta['ATTITUDE_TYPE']!r} is not supported in CCSDS_AEM_VERS "
                        f"{'2.0' if v2 else '1.0'} (use {', '.join(types)})")
    qtype = _quaternion_type(meta, v2, src)
    frame = a if frame is None else frame
    if not (same_frame(frame, a) or same_frame(frame, b)):
        raise UserError(f"{src}: neither REF_FRAME_A {a!r} nor REF_FRAME_B {b!r} is the trajectory frame {frame!r}")
    width = _WIDTH[att_type]
    epochs, vals, labels = _epochs_values(segments, (width,), src, att_type)
    q = vals[:, [1, 2, 3, 0]] if qtype == "FIRST" else vals[:, 0:4]
    # an X2Y quaternion is R_X_from_Y: invert unless X is the trajectory frame
    from_frame = a if direction == "A2B" else b
    if not same_frame(from_frame, frame):
        q = q * np.array([-1.0, -1.0, -1.0, 1.0])
    cam = b if same_frame(frame, a) else a
    return PoseSeries(times_s=np.array([e.minus(epochs[0]) for e in epochs]), positions_m=None, quat_xyzw=q,
                      frame=frame, epoch0=epochs[0], source=src, attitude_frame=cam,
                      object_name=meta["OBJECT_NAME"], center_name=meta.get("CENTER_NAME"), labels=labels)


def _header(originator: str, creation_date: str | None) -> dict[str, str]:
    now = datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%S")
    return {"CREATION_DATE": creation_date or now, "ORIGINATOR": originator}


def _epoch_texts(series: PoseSeries, epoch0, time_system: str) -> list[str]:
    if series.epoch0 is None and epoch0 is None:
        raise UserError(f"{series.source}: has relative times only; give the epoch of time 0 (epoch_utc) to write "
                        "a CCSDS message")
    base = series.epoch0 if epoch0 is None else (epoch0 if isinstance(epoch0, Epoch) else parse_epoch(epoch0))
    return [base.plus(float(t)).iso(time_system, 9).rstrip("Z") for t in series.times_s]


def write_oem(path, series: PoseSeries, *, object_name: str | None = None, object_id: str = "UNKNOWN",
              center_name: str | None = None, time_system: str = "UTC", epoch0=None,
              originator: str = "renderlab", creation_date: str | None = None) -> None:
    """Write the positions of ``series`` as a one-segment KVN OEM 2.0 (km, km/s).

    Velocities come from the series, else from the derivative of a cubic spline through the positions.
    ``epoch0`` (Epoch or ISO UTC) is the epoch of time 0 for a relative-time series.
    """
    from scipy.interpolate import CubicSpline

    if series.positions_m is None:
        raise UserError(f"{series.source}: has no positions to write")
    texts = _epoch_texts(series, epoch0, time_system)
    vel = series.velocities_m_s
    if vel is None:
        vel = (np.zeros_like(series.positions_m) if len(series.times_s) == 1
               else CubicSpline(series.times_s, series.positions_m, axis=0)(series.times_s, 1))
    meta = {"OBJECT_NAME": object_name or series.object_name or "CAMERA", "OBJECT_ID": object_id,
            "CENTER_NAME": center_name or series.center_name or "ORIGIN", "REF_FRAME": series.frame,
            "TIME_SYSTEM": time_system, "START_TIME": texts[0], "STOP_TIME": texts[-1]}
    rows = np.hstack([series.positions_m, vel]) / 1e3
    data = [" ".join([t, *(repr(float(v)) for v in row)]) for t, row in zip(texts, rows)]
    write_kvn(path, "OEM", "2.0", _header(originator, creation_date), meta, data, data_block=False)


def write_aem(path, series: PoseSeries, *, object_name: str | None = None, object_id: str = "UNKNOWN",
              camera_frame: str | None = None, attitude_dir: str = "A2B", quaternion_type: str = "LAST",
              time_system: str = "UTC", epoch0=None, originator: str = "renderlab",
              creation_date: str | None = None) -> None:
    """Write the attitude of ``series`` as a one-segment KVN AEM 1.0 (``REF_FRAME_A`` = the series frame,
    ``REF_FRAME_B`` = the camera), quaternions per ``attitude_dir`` and ``quaternion_type``."""
    if series.quat_xyzw is None:
        raise UserError(f"{series.source}: has no attitude to write")
    if attitude_dir not in ("A2B", "B2A") or quaternion_type not in ("FIRST", "LAST"):
        raise UserError(f"attitude_dir must be A2B or B2A and quaternion_type FIRST or LAST, got "
                        f"{attitude_dir!r}, {quaternion_type!r}")
    texts = _epoch_texts(series, epoch0, time_system)
    q = Rotation.from_quat(series.quat_xyzw)
    q = (q if attitude_dir == "A2B" else q.inv()).as_quat()
    if quaternion_type == "FIRST":
        q = q[:, [3, 0, 1, 2]]
    meta = {"OBJECT_NAME": object_name or series.object_name or "CAMERA", "OBJECT_ID": object_id,
            "REF_FRAME_A": series.frame, "REF_FRAME_B": camera_frame or series.attitude_frame or "CAMERA",
            "ATTITUDE_DIR": attitude_dir, "TIME_SYSTEM": time_system, "START_TIME": texts[0],
            "STOP_TIME": texts[-1], "ATTITUDE_TYPE": "QUATERNION", "QUATERNION_TYPE": quaternion_type,
            "INTERPOLATION_METHOD": "LINEAR"}
    data = [" ".join([t, *(repr(float(v)) for v in row)]) for t, row in zip(texts, q)]
    write_kvn(path, "AEM", "1.0", _header(originator, creation_date), meta, data, data_block=True)
