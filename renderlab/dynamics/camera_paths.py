"""Simple camera paths for analytic scenes.

``line``: the camera moves at constant velocity from ``start_m`` to ``end_m``;
``orbit``: the camera moves on a circle of radius ``range_m·cos(elevation)`` at height
``range_m·sin(elevation)`` above ``target_m`` (azimuth measured from +x toward +y).
In both cases it looks at ``target_m`` with ``up`` toward the top of the image.
``table``, ``ccsds``, ``spice``: the user's own trajectory, read from files by :mod:`renderlab.trajectory_io`
(relative paths against the scenario folder ``base_dir``), in the frame the files declare; every world takes them
and says what that frame is to it (:func:`check_frame`; the analytic world: its scene frame).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from renderlab.errors import UserError
from renderlab.geometry.rotations import look_at
from renderlab.trajectory_io.sources import frame_poses


@dataclass(frozen=True)
class CameraPose:
    """A camera pose: ``p_render = rotation.apply(p_cam) + position_m``."""

    time_s: float
    position_m: np.ndarray
    rotation: Rotation  # R_render_from_cam
    epoch_utc: str | None = None  # ISO UTC of the frame, when the trajectory has epochs


#: trajectory kinds read from the user's files (:mod:`renderlab.trajectory_io`)
FILE_KINDS = ("table", "ccsds", "spice")


def _frame_key(name) -> str:
    return str(name).strip().upper().replace("-", "").replace("_", "").replace(" ", "")


def file_poses(fp, traj) -> list[CameraPose]:
    """The camera poses of a sampled file trajectory (:func:`renderlab.trajectory_io.sources.frame_poses`), in the
    frame its files declare; UserError when the files give no attitude (worlds with a default pointing, the
    Earth's nadir, read ``fp`` themselves)."""
    if fp.rotations is None:
        raise UserError(f"trajectory: {traj.missing_attitude()}; this world has no default pointing")
    return [CameraPose(time_s=float(t), position_m=p, rotation=fp.rotations[k],
                       epoch_utc=None if fp.epochs_utc is None else fp.epochs_utc[k])
            for k, (t, p) in enumerate(zip(fp.times_s, fp.positions_m))]


def check_frame(fp, traj, accepted: dict[str, tuple[str, ...]], world: str, table_default: str | None = None) -> str:
    """Which of a world's frames a file trajectory is in, by the name its files declare.

    Parameters
    ----------
    fp : FramePoses
        The sampled trajectory (:func:`renderlab.trajectory_io.sources.frame_poses`): ``frame`` is the OEM's
        ``REF_FRAME``, the SPICE ``frame`` or the table's ``trajectory.frame``.
    traj : SourceTrajectoryConfig
        The scenario's ``[trajectory]`` (a table without ``frame`` declares none).
    accepted : dict
        The world's frames → the names that mean each (compared without case, ``-``, ``_`` and blanks).
    world : str
        The world kind, for the message.
    table_default : str, optional
        The key of ``accepted`` a table without ``frame`` is taken in; None: such a table is refused.

    Returns
    -------
    str
        The key of ``accepted`` the trajectory is in.

    Raises
    ------
    UserError
        One line naming the frame and the names the world accepts.
    """
    names = ", ".join(repr(ns[0]) for ns in accepted.values())
    if traj.kind == "table" and traj.frame is None:
        if table_default is not None:
            return table_default
        raise UserError(f"trajectory.frame: world.kind '{world}' needs the table's frame ({names})")
    for key, aliases in accepted.items():
        if _frame_key(fp.frame) in {_frame_key(a) for a in aliases}:
            return key
    where = "the OEM's REF_FRAME" if traj.kind == "ccsds" else "trajectory.frame"
    raise UserError(f"trajectory: {where} {fp.frame!r} is not a frame world.kind '{world}' can use ({names})")


def _fractions(n: int) -> np.ndarray:
    return np.zeros(1) if n == 1 else np.linspace(0.0, 1.0, n)


def camera_path(traj, base_dir: str | Path | None = None) -> list[CameraPose]:
    """Camera poses for every frame of a camera-path trajectory.

    Parameters
    ----------
    traj : TrajectoryConfig or SourceTrajectoryConfig
        The scenario's ``[trajectory]``: ``line``/``orbit``, or a file kind (``table``, ``ccsds``, ``spice``).
    base_dir : path, optional
        The scenario folder, against which a file trajectory's relative paths resolve (default: the working
        directory).

    Returns
    -------
    list of CameraPose
        One pose per frame (``epoch_utc`` set for file trajectories with epochs).
    """
    if traj.kind in FILE_KINDS:

        return file_poses(frame_poses(traj, base_dir), traj)
    target = np.asarray(traj.target_m, float)
    up = np.asarray(traj.up, float)
    fr = _fractions(traj.frames)
    if traj.kind == "line":
        start = np.asarray(traj.start_m, float)
        end = np.asarray(traj.end_m if traj.end_m is not None else traj.start_m, float)
        positions = start[None, :] + fr[:, None] * (end - start)[None, :]
    else:
        az = np.radians(traj.azimuth_start_deg + fr * (traj.azimuth_end_deg - traj.azimuth_start_deg))
        el = np.radians(traj.elevation_deg)
        offs = traj.range_m * np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.full_like(az, np.sin(el))], 1)
        positions = target[None, :] + offs
    poses = []
    for k, pos in enumerate(positions):
        if np.linalg.norm(target - pos) < 1e-9:
            raise UserError(f"trajectory: frame {k} puts the camera on its target {target.tolist()}")
        poses.append(CameraPose(time_s=k * traj.dt_s, position_m=pos, rotation=look_at(pos, target, up)))
    return poses
