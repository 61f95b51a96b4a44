"""The spacecraft of every frame of the Earth world (:class:`FrameOrbit`), made by the ``leo`` orbit
(:func:`renderlab.worlds.earth.plan.leo_orbit`) or a file trajectory
(:func:`renderlab.worlds.earth.file_trajectory.file_orbit`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from renderlab.geometry.camera import CameraModel


@dataclass(frozen=True)
class FrameOrbit:
    """The spacecraft of every frame, whatever the trajectory: GCRF state, true attitude, what the star tracker
    reports, the epochs and Earth orientation (the ``leo`` orbit: :func:`leo_orbit`; a file trajectory:
    :func:`renderlab.worlds.earth.file_trajectory.file_orbit`)."""

    camera: CameraModel
    epoch: object                 # datetime (UTC) of elapsed time 0
    time_s: np.ndarray            # (N,) frame times on the trajectory's axis
    elapsed_s: np.ndarray         # (N,) SI seconds after ``epoch`` (Earth orientation, sun)
    epochs_utc: list              # (N,) ISO UTC of each frame (the manifest's epoch_utc)
    r_eci: np.ndarray             # (N, 3) GCRF position, m
    v_eci: np.ndarray             # (N, 3) GCRF velocity, m/s
    R_eci_from_cam: np.ndarray    # (N, 3, 3) true attitude
    R_eci_from_cam_st: np.ndarray  # (N, 3, 3) the star tracker's
    eo: object                    # orientation.EarthOrientation at the frame epochs
    model: str                    # the manifest's truth_orbit_model
    star_tracker_sigma_arcsec: float
