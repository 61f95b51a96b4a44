"""A file trajectory (``trajectory.kind = "table" | "ccsds" | "spice"``) over EV5: what it means in this world.

* **Frame.** The files give the camera pose in the asteroid body-fixed frame ``EV5_FIXED``, the world's render
  frame (origin at the body's centre, +z the spin pole; the frame of ``site.json`` and the shape): the OEM's
  ``REF_FRAME``, the SPICE ``frame`` or the table's ``trajectory.frame`` must name it (a table without ``frame`` is
  taken in it). Positions in metres, attitude ``R_EV5_FIXED_from_cam`` (lab camera axes: +z boresight, +x right,
  +y down), or ``attitude = "look_at"``; the files must give the attitude (no default pointing here).
* **Time.** Frame times are the trajectory's (seconds after ``epoch_utc`` or the file's first epoch, or a table's
  ``time_s``); the spin state of each frame is taken at that time (rotation angle W0 + ω t).
* **Sun.** ``[sun] direction`` is the direction toward the sun in ``EV5_FIXED`` at time 0; the sun is fixed in
  inertial space, so in the body frame it turns with the spin: s_B(t) = Rz(−ω t) s_B(0), as in the descent
  (:mod:`.descent`). ``[sun] irradiance_w_m2`` as everywhere.
* **Per frame** the manifest's ``ev5`` record carries ``altitude_m`` (above the site centre along its normal, as in
  the descent), the spin state and the sun in the ecliptic frame; ``spin_matched`` belongs to the descent only.
"""

from __future__ import annotations

import numpy as np

from renderlab.dynamics.camera_paths import check_frame
from renderlab.dynamics.camera_paths import file_poses as camera_file_poses
from renderlab.dynamics.small_body import SpinState
from renderlab.worlds.ev5.descent import DescentState

#: the frame a file trajectory is read in, and the names that mean it
FRAMES = {"EV5_FIXED": ("EV5_FIXED", "EV5_BODY_FIXED")}


def file_poses(traj, base_dir) -> list:
    """The camera poses of a file trajectory in ``EV5_FIXED``, the files read once and their frame checked."""
    from renderlab.trajectory_io.sources import frame_poses

    fp = frame_poses(traj, base_dir)
    check_frame(fp, traj, FRAMES, "ev5", table_default="EV5_FIXED")
    return camera_file_poses(fp, traj)


def file_states(poses, sun_direction, spin: SpinState, origin: np.ndarray,
                R_body_from_site: np.ndarray) -> list[DescentState]:
    """The frames of a file trajectory as :class:`DescentState` (module docstring).

    Parameters
    ----------
    poses : list of CameraPose
        From :func:`file_poses` (``EV5_FIXED``).
    sun_direction : array_like
        ``[sun] direction``: toward the sun in ``EV5_FIXED`` at time 0 (any length).
    spin : SpinState
        The asteroid's spin.
    origin, R_body_from_site : numpy.ndarray
        The landing site's centre and axes (its normal is the third column).
    """
    s0 = np.asarray(sun_direction, float)
    s0 = s0 / np.linalg.norm(s0)
    normal = np.asarray(R_body_from_site)[:, 2]
    out = []
    for p in poses:
        sun = spin.inertial_to_body_turn(p.time_s)[0].apply(s0)
        h = float(np.dot(p.position_m - origin, normal))
        out.append(DescentState(float(p.time_s), h, p, sun, None))
    return out
