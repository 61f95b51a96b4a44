"""A file trajectory of a scenario (``kind = "table" | "ccsds" | "spice"``) → the camera pose of every frame.

The scenario section is :class:`renderlab.scenario.trajectory.SourceTrajectoryConfig`; this module reads it by
attribute only (no scenario import: the dynamics layer calls it). Files resolve against the scenario folder.

Frame times: on a ``time_s`` table's own axis, or SI seconds after the start epoch (``epoch_utc``, default the
source's first epoch) on the TT scale, as TAI and UTC count them: a frame's UTC label is plain UTC arithmetic
(``12:00:00Z`` + 3600 s = ``13:00:00Z``, exact), a leap second in between aside; SPICE gets the TDB of each instant
(:mod:`renderlab.trajectory_io.timescales`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from renderlab.errors import UserError
from renderlab.geometry.rotations import look_at
from renderlab.trajectory_io.ccsds import read_aem, read_oem, same_frame
from renderlab.trajectory_io.series import PoseSeries
from renderlab.trajectory_io.spice import read_spice, read_spice_sun
from renderlab.trajectory_io.table import read_table
from renderlab.trajectory_io.timescales import Epoch, parse_epoch


@dataclass(frozen=True)
class FramePoses:
    """Camera poses at the frame times.

    Attributes
    ----------
    times_s : numpy.ndarray, shape (n,)
        Frame times on the trajectory's axis (seconds after the start epoch, or the table's ``time_s``).
    positions_m : numpy.ndarray, shape (n, 3)
        Camera positions in the trajectory frame.
    rotations : scipy.spatial.transform.Rotation or None
        ``R_frame_from_cam`` of every frame; None when the files give positions only (no attitude keys: the
        world's default pointing applies).
    epochs_utc : list of str or None
        ISO UTC epoch of every frame (None for a relative-time table).
    frame : str
        The trajectory frame's name (a table without ``frame``: ``SCENE``).
    velocities_m_s : numpy.ndarray, shape (n, 3), or None
        Camera velocities in the trajectory frame: the derivative of the interpolated positions (OEM, table), the
        SPK state (SPICE, when asked for); None where the source cannot give them.
    center : str or None
        The origin of the frame as the source names it (OEM ``CENTER_NAME``, SPICE ``center``; None for a table).
    """

    times_s: np.ndarray
    positions_m: np.ndarray
    rotations: Rotation | None
    epochs_utc: list[str] | None
    frame: str
    velocities_m_s: np.ndarray | None = None
    center: str | None = None


def resolve(base_dir, rel: str, key: str) -> Path:
    """``rel`` against the scenario folder; UserError naming ``trajectory.<key>`` when the file is missing."""
    p = Path(rel)
    if not p.is_absolute():
        p = Path(base_dir if base_dir is not None else ".") / p
    if not p.is_file():
        raise UserError(f"trajectory.{key}: file not found: {rel}")
    return p.resolve()


def _same(a: str, b: str) -> bool:
    return same_frame(a, b)


def _read_ccsds(traj, base_dir) -> tuple[PoseSeries, PoseSeries | None]:
    oem = read_oem(resolve(base_dir, traj.oem, "oem"))
    if traj.frame is not None and not _same(traj.frame, oem.frame):
        raise UserError(f"trajectory.frame {traj.frame!r} is not {oem.source}'s REF_FRAME {oem.frame!r}")
    for key, have in (("observer", oem.object_name), ("center", oem.center_name)):
        want = getattr(traj, key)
        if want is not None and want.strip().upper() != str(have).strip().upper():
            raise UserError(f"trajectory.{key} {want!r} is not {oem.source}'s "
                            f"{'OBJECT_NAME' if key == 'observer' else 'CENTER_NAME'} {have!r}")
    if not traj.reads_attitude():
        return oem, None
    aem = read_aem(resolve(base_dir, traj.aem, "aem"), frame=oem.frame)
    if aem.object_name.strip().upper() != oem.object_name.strip().upper():
        raise UserError(f"{aem.source} is for OBJECT_NAME {aem.object_name!r}, {oem.source} for {oem.object_name!r}")
    if traj.camera_frame is not None and not _same(traj.camera_frame, aem.attitude_frame):
        raise UserError(f"trajectory.camera_frame {traj.camera_frame!r} is not {aem.source}'s camera-side frame "
                        f"{aem.attitude_frame!r}")
    return oem, aem


def _read_files(traj, base_dir) -> tuple[PoseSeries, PoseSeries | None]:
    if traj.kind == "table":

        s = read_table(resolve(base_dir, traj.file, "file"), quaternion_order=traj.quaternion_order,
                       quaternion_direction=traj.quaternion_direction, frame=traj.frame or "SCENE",
                       attitude=traj.reads_attitude())
        return s, (s if traj.reads_attitude() else None)
    if traj.kind == "ccsds":
        return _read_ccsds(traj, base_dir)
    raise UserError(f"trajectory.kind {traj.kind!r} is not a file trajectory")


def _start(traj, pos: PoseSeries) -> Epoch | None:
    if pos.epoch0 is None:
        if traj.epoch_utc is not None:
            raise UserError(f"trajectory.epoch_utc: {pos.source} has relative times (time_s), not epochs; drop "
                            "epoch_utc or give the table an epoch column")
        return None
    return parse_epoch(traj.epoch_utc, "UTC", "trajectory.epoch_utc") if traj.epoch_utc else pos.epoch0


def _offset(series: PoseSeries, start: Epoch | None) -> float:
    if (series.epoch0 is None) != (start is None):
        raise UserError(f"{series.source}: mixes relative times and epochs with the other trajectory file")
    return 0.0 if start is None else start.minus(series.epoch0)


def _spice(traj, base_dir, t: np.ndarray, velocities: bool):
    kernels = [resolve(base_dir, k, f"kernels.{i}") for i, k in enumerate(traj.kernels)]
    s = read_spice(kernels, observer=traj.observer, center=traj.center, frame=traj.frame,
                   camera_frame=traj.camera_frame if traj.reads_attitude() else None,
                   epoch_utc=traj.epoch_utc, times_s=t, velocities=velocities, aberration=traj.aberration)
    rots = Rotation.from_quat(s.quat_xyzw) if s.quat_xyzw is not None else None
    return s.positions_m, rots, s.epoch0, s.velocities_m_s


def _look_at(traj, positions: np.ndarray) -> Rotation:
    target = np.asarray(traj.target_m, float)
    rots = []
    for k, p in enumerate(positions):
        if np.linalg.norm(target - p) < 1e-9:
            raise UserError(f"trajectory: frame {k} puts the camera on its target {target.tolist()}")
        rots.append(look_at(p, target, traj.up).as_quat())
    return Rotation.from_quat(np.array(rots))


def frame_poses(traj, base_dir=None, velocities: bool = False) -> FramePoses:
    """Read the trajectory's files and sample the camera pose of every frame (module docstring).

    Parameters
    ----------
    traj : SourceTrajectoryConfig
        The scenario's ``[trajectory]`` (kind ``table``, ``ccsds`` or ``spice``).
    base_dir : path, optional
        The scenario folder (relative file names resolve against it; default: the working directory).
    velocities : bool
        Ask SPICE for velocities too (``spkezr``); tables and OEMs always give them (the derivative of the
        interpolated positions).

    Raises
    ------
    UserError
        Any problem with the files (one line), a frame time outside their coverage.
    """
    t = np.asarray(traj.frame_times(), float)
    if traj.kind == "spice":
        positions, rots, start, vel = _spice(traj, base_dir, t, velocities)
        frame, center = traj.frame, traj.center
    else:
        pos, att = _read_files(traj, base_dir)
        start = _start(traj, pos)
        positions = pos.positions_at(t + _offset(pos, start), traj.interpolation)
        vel = pos.velocities_at(t + _offset(pos, start), traj.interpolation)
        rots = att.attitude_at(t + _offset(att, start)) if att is not None else None  # (see series.check_covers)
        frame, center = pos.frame, pos.center_name
    if traj.attitude == "look_at":
        rots = _look_at(traj, positions)
    elif rots is not None and traj.camera_mount_quat_xyzw is not None:
        rots = rots * Rotation.from_quat(traj.camera_mount_quat_xyzw)
    epochs = None if start is None else [start.plus(float(v)).iso("UTC", 6) for v in t]
    return FramePoses(times_s=t, positions_m=positions, rotations=rots, epochs_utc=epochs, frame=frame,
                      velocities_m_s=vel, center=center)


def spice_sun(traj, base_dir=None) -> np.ndarray:
    """The sun relative to the scene's centre at every frame of a ``spice`` trajectory, in its frame (m)
    (:func:`renderlab.trajectory_io.spice.read_spice_sun`: ``sun.source = "spice"``, with ``trajectory.aberration``).

    Raises
    ------
    UserError
        Not a ``spice`` trajectory, no SPK with the Sun, and what :func:`frame_poses` refuses.
    """
    if traj.kind != "spice":
        raise UserError(f"sun.source = \"spice\" needs trajectory.kind = \"spice\", got {traj.kind!r}")
    kernels = [resolve(base_dir, k, f"kernels.{i}") for i, k in enumerate(traj.kernels)]
    return read_spice_sun(kernels, observer=traj.observer, center=traj.center, frame=traj.frame,
                          epoch_utc=traj.epoch_utc, times_s=np.asarray(traj.frame_times(), float),
                          aberration=traj.aberration)


def source_names(traj, base_dir=None) -> dict[str, str]:
    """The names the user's files give the trajectory's frame, its origin and the camera's body, for a truth set's
    manifest (``renderlab export`` writes them back): ``frame`` (OEM ``REF_FRAME``, SPICE ``frame``, a table's
    ``trajectory.frame``), ``center`` (OEM ``CENTER_NAME``, SPICE ``center``), ``object`` (OEM ``OBJECT_NAME``,
    SPICE ``observer``); a name the source does not give is left out."""
    names = {"frame": traj.frame, "center": traj.center if traj.kind != "table" else None,
             "object": traj.observer if traj.kind != "table" else None}
    if traj.kind == "ccsds":

        oem = read_oem(resolve(base_dir, traj.oem, "oem"))
        names = {"frame": oem.frame, "center": oem.center_name, "object": oem.object_name}
    return {k: str(v) for k, v in names.items() if v}
