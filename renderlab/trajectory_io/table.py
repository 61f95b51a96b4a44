"""Pose tables: CSV or Parquet, one row per sample.

Columns (names carry the units; other columns are ignored):

* time: ``time_s`` (seconds on the table's own axis) **or** ``epoch`` (ISO UTC text, or a Parquet timestamp read
  as UTC);
* position: ``x_m, y_m, z_m`` (or ``x_km, y_km, z_km``) in the table's frame;
* velocity, optional (cubic Hermite interpolation): ``vx_m_s, vy_m_s, vz_m_s`` (or ``vx_km_s``…);
* attitude: ``qx, qy, qz, qw``, the unit quaternion of the camera attitude. The scenario declares the order the
  columns stand in (``quaternion_order = "xyzw" | "wxyz"``; a file whose columns stand otherwise is refused)
  and the direction: ``cam_to_frame`` when ``Rotation.from_quat([qx, qy, qz, qw])`` maps camera-frame
  coordinates to frame coordinates (``R_frame_from_cam``, the lab's and the manifest's convention),
  ``frame_to_cam`` for its inverse (a SPICE C-matrix quaternion, for one).

The camera frame is the lab's: +z boresight, +x right in the image, +y down.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from renderlab.errors import UserError
from renderlab.trajectory_io.series import PoseSeries
from renderlab.trajectory_io.timescales import Epoch, parse_epoch

QUAT_COLUMNS = {"xyzw": ("qx", "qy", "qz", "qw"), "wxyz": ("qw", "qx", "qy", "qz")}
DIRECTIONS = ("cam_to_frame", "frame_to_cam")


def _read(path: Path):
    """The file as a pyarrow table (UserError with one line when it cannot be read)."""
    import pyarrow as pa

    suffix = path.suffix.lower()
    try:
        if suffix == ".csv":
            import pyarrow.csv as pacsv

            return pacsv.read_csv(path, convert_options=pacsv.ConvertOptions(column_types={"epoch": pa.string()}))
        if suffix in (".parquet", ".pq"):
            import pyarrow.parquet as pq

            return pq.read_table(path)
    except (pa.ArrowInvalid, OSError) as err:
        raise UserError(f"{path.name}: cannot read the table ({str(err).splitlines()[0]})") from None
    raise UserError(f"{path.name}: a pose table must be .csv or .parquet, got '{suffix or path.name}'")


def _column(table, name: str, src: str) -> np.ndarray:
    import pyarrow as pa

    col = table.column(name)
    if not (pa.types.is_integer(col.type) or pa.types.is_floating(col.type)):
        raise UserError(f"{src}: column {name} must be numbers, got {col.type}")
    if col.null_count:
        row = int(np.flatnonzero(col.is_null().to_numpy(zero_copy_only=False))[0]) + 1
        raise UserError(f"{src}: column {name} has no value (empty or NaN) at row {row}")
    return col.to_numpy(zero_copy_only=False).astype(float)


def _vector(table, names: list[str], stems: tuple[str, ...], units: dict[str, float], src: str, need: bool):
    """Three columns ``<stem><unit>`` with one unit for all three (scaled to SI), or None."""
    for suffix, scale in units.items():
        cols = [s + suffix for s in stems]
        have = [c for c in cols if c in names]
        if len(have) == 3:
            return np.stack([_column(table, c, src) for c in cols], axis=1) * scale
        if have:
            raise UserError(f"{src}: missing column(s) {', '.join(c for c in cols if c not in names)} "
                            f"(found {', '.join(have)})")
    if need:
        options = " or ".join(", ".join(s + u for s in stems) for u in units)
        raise UserError(f"{src}: missing columns {options} (columns: {', '.join(names)})")
    return None


def _times(table, names: list[str], src: str) -> tuple[np.ndarray, Epoch | None]:
    """Relative times and the epoch of time zero (None for ``time_s``)."""
    import pyarrow as pa

    if ("time_s" in names) == ("epoch" in names):
        what = "both time_s and epoch" if "time_s" in names else "no time_s or epoch column"
        raise UserError(f"{src}: {what} (give one: time_s in seconds or epoch as ISO UTC)")
    if "time_s" in names:
        return _column(table, "time_s", src), None
    col = table.column("epoch")
    if col.null_count:
        row = int(np.flatnonzero(col.is_null().to_numpy(zero_copy_only=False))[0]) + 1
        raise UserError(f"{src}: column epoch is empty at row {row}")
    if pa.types.is_timestamp(col.type):
        ns = col.cast(pa.timestamp("ns")).to_numpy(zero_copy_only=False).astype("datetime64[ns]")
        text = [str(v) for v in ns]
    elif pa.types.is_string(col.type) or pa.types.is_large_string(col.type):
        text = col.to_pylist()
    else:
        raise UserError(f"{src}: column epoch must be ISO UTC text or a timestamp, got {col.type}")
    epochs = [parse_epoch(s, "UTC", f"{src} row {i + 1} epoch") for i, s in enumerate(text)]
    return np.array([e.minus(epochs[0]) for e in epochs]), epochs[0]


def read_table(path, *, quaternion_order: str | None = "xyzw", quaternion_direction: str | None = "cam_to_frame",
               frame: str = "SCENE", attitude: bool = True) -> PoseSeries:
    """Read a CSV or Parquet pose table (module docstring) into a :class:`PoseSeries`.

    Parameters
    ----------
    path : str or os.PathLike
        The table file (``.csv`` or ``.parquet``).
    quaternion_order : {"xyzw", "wxyz"}
        The order of the quaternion columns in the file (checked against the file).
    quaternion_direction : {"cam_to_frame", "frame_to_cam"}
        What the quaternion maps (module docstring).
    frame : str
        Name of the frame positions and attitude are given in.
    attitude : bool
        Whether the quaternion columns are required (False: positions only; quaternion columns are ignored).

    Raises
    ------
    UserError
        Missing file or columns, non-numeric or empty cells, non-increasing time, non-unit quaternions, a
        declared order the columns contradict.
    """
    path = Path(path)
    src = path.name
    if not path.is_file():
        raise UserError(f"pose table not found: {path}")
    table = _read(path)
    names = list(table.column_names)
    if table.num_rows == 0:
        raise UserError(f"{src}: the table has no rows")
    times, epoch0 = _times(table, names, src)
    pos = _vector(table, names, ("x", "y", "z"), {"_m": 1.0, "_km": 1e3}, src, need=True)
    vel = _vector(table, names, ("vx", "vy", "vz"), {"_m_s": 1.0, "_km_s": 1e3}, src, need=False)
    quat = _quaternions(table, names, quaternion_order, quaternion_direction, src) if attitude else None
    labels = tuple(f"row {i + 1}" for i in range(table.num_rows))
    return PoseSeries(times_s=times, positions_m=pos, quat_xyzw=quat, frame=frame, epoch0=epoch0,
                      velocities_m_s=vel, source=src, labels=labels)


def _quaternions(table, names: list[str], order: str | None, direction: str | None, src: str) -> np.ndarray:
    if order not in QUAT_COLUMNS:
        raise UserError(f"quaternion_order must be 'xyzw' or 'wxyz', got {order!r}")
    if direction not in DIRECTIONS:
        raise UserError(f"quaternion_direction must be 'cam_to_frame' or 'frame_to_cam', got {direction!r}")
    missing = [c for c in QUAT_COLUMNS["xyzw"] if c not in names]
    if missing:
        raise UserError(f"{src}: missing quaternion column(s) {', '.join(missing)} (columns: {', '.join(names)})")
    in_file = tuple(sorted(QUAT_COLUMNS["xyzw"], key=names.index))
    if in_file != QUAT_COLUMNS[order]:
        raise UserError(f"{src}: quaternion columns stand in the order {', '.join(in_file)} but quaternion_order "
                        f"is '{order}' ({', '.join(QUAT_COLUMNS[order])}); fix the declaration or the file")
    q = np.stack([_column(table, c, src) for c in QUAT_COLUMNS["xyzw"]], axis=1)
    if direction == "frame_to_cam":
        q = q * np.array([-1.0, -1.0, -1.0, 1.0])
    return q
