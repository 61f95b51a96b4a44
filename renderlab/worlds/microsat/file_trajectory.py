"""A file trajectory (``trajectory.kind = "table" | "ccsds" | "spice"``) in the microsat world: the chaser's camera
relative to the tumbling target.

* **Frame.** The files give the camera's position relative to the target's centre of mass, and its attitude, in the
  chaser's ``LVLH`` frame (:mod:`renderlab.dynamics.relative_motion`: +x radial, +y along-track, +z orbit normal; the
  CCSDS/SPICE names ``RTN``, ``RSW`` and ``RIC`` mean the same axes): the OEM's ``REF_FRAME``, the SPICE ``frame`` or
  the table's ``trajectory.frame`` must name it (an OEM's ``CENTER_NAME`` is then the target). Attitude
  ``R_lvlh_from_cam`` (lab camera axes), or ``attitude = "look_at"`` (LVLH ``target_m``); the files must give it.
* **Tumble.** As with the ``separation`` trajectory: Euler + gravity gradient from ``[world.tumble]`` (attitude and
  body rate at trajectory time 0), so frame times (seconds after ``epoch_utc`` or the file's first epoch, or a
  table's ``time_s``) must not be negative. The render frame stays the target's body frame (``MICROSAT_BODY``):
  ``position_body = Rᵀ p_lvlh``, ``R_body_from_cam = Rᵀ R_lvlh_from_cam`` with R = ``R_lvlh_from_body``.
* **Sun.** ``world.sun_lvlh`` at time 0, inertially fixed (seen in LVLH as Rz(−n t) s0).
* **Manifest.** The ``microsat`` record keeps its keys with the camera as the chaser's reference point:
  ``camera_offset_lvlh_m`` = 0, ``r_lvlh_m``/``v_lvlh_mps`` the target relative to the camera (the file's state
  negated; ``v`` null where the source has no velocity) and ``quat_lvlh_from_cam_xyzw`` the file's attitude of that
  frame (it may change from frame to frame, unlike the separation's fixed camera).
"""

from __future__ import annotations

import numpy as np

from renderlab.dynamics.attitude import propagate_attitude
from renderlab.dynamics.camera_paths import check_frame, file_poses
from renderlab.dynamics.relative_motion import mean_motion, sun_in_lvlh
from renderlab.errors import UserError

#: the frame a file trajectory is read in, and the names that mean it
FRAMES = {"LVLH": ("LVLH", "RTN", "RSW", "RIC")}


def file_truth(scenario, base_dir, features_body):
    """The :class:`~renderlab.worlds.microsat.truth.SeparationTruth` of a file trajectory (module docstring): the
    files read once (:func:`renderlab.trajectory_io.sources.frame_poses`), their frame checked."""
    from renderlab.trajectory_io.sources import frame_poses
    from renderlab.worlds.microsat.config import MicrosatTumble
    from renderlab.worlds.microsat.truth import SeparationTruth

    traj, world = scenario.trajectory, scenario.world
    fp = frame_poses(traj, base_dir, velocities=True)
    check_frame(fp, traj, FRAMES, "microsat")
    poses = file_poses(fp, traj)
    times = np.asarray(fp.times_s, float)
    if times[0] < 0:
        raise UserError(f"trajectory: frame 0 is at {times[0]:g} s, before time 0 where [world.tumble] holds (the "
                        "microsat target's tumble starts at trajectory time 0)")
    tumble = world.tumble or MicrosatTumble()
    n = mean_motion(tumble.altitude_m)
    q0 = np.asarray(tumble.q0_lvlh_from_body_xyzw, float)
    grid = times if times[0] == 0 else np.concatenate([[0.0], times])
    Q, W = propagate_attitude(q0 / np.linalg.norm(q0), np.radians(tumble.omega0_body_deg_s), world.inertia_kg_m2,
                              n, grid, substeps=tumble.attitude_substeps)
    Q, W = Q[len(grid) - len(times):], W[len(grid) - len(times):]
    vel = fp.velocities_m_s if fp.velocities_m_s is not None else np.full_like(fp.positions_m, np.nan)
    rv = -np.hstack([fp.positions_m, vel])  # the target relative to the camera
    R_lc = np.array([p.rotation.as_matrix() for p in poses])
    sun = np.array([sun_in_lvlh(world.sun_lvlh, n, t) for t in times])
    return SeparationTruth(times, rv, Q, W, np.asarray(world.inertia_kg_m2, float), n, np.zeros(3), R_lc, sun,
                           np.asarray(features_body, float), fp.epochs_utc)
