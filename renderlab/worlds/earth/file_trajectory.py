"""A file trajectory (``trajectory.kind = "table" | "ccsds" | "spice"``) in the Earth world: the spacecraft's own
state instead of the ``leo`` orbit.

* **Frame.** The files give the camera (spacecraft) state in ``GCRF`` (also spelled ``GCRS``, or ``ICRF`` axes about
  the Earth) or in ``ITRF`` (``ITRS``, ``ITRF93``, ``ITRF2014``…: taken as the lab's ITRF, the realisations agree to
  centimetres), as the OEM's ``REF_FRAME``, the SPICE ``frame`` or the table's ``trajectory.frame`` declares; the
  origin is the Earth's centre (an OEM's ``CENTER_NAME`` or the SPICE ``center`` must be ``EARTH`` or ``399``).
  ``J2000``/``EME2000`` are refused: they differ from GCRF by the 23 mas frame bias (about a metre in LEO).
  ITRF states become GCRF through the world's own Earth orientation (:mod:`.orientation`):
  r = Mᵀ r_ITRF, v = Mᵀ (v_ITRF + ω⊕ ẑ × r_ITRF).
* **Epochs** come from the files (``epoch_utc`` or the file's first epoch, plus the frame times): the Earth
  rotation and the sun need them, so a table with relative ``time_s`` only is refused.
* **Attitude** from the AEM, the SPICE camera frame or the table's quaternions when given (``R_frame_from_cam`` in
  the trajectory's frame); otherwise the world's default pointing, nadir (:func:`renderlab.dynamics.orbits.
  nadir_attitude`: boresight to the geocentre, image top along the velocity). The star tracker reports it without
  noise (``star_tracker_sigma_arcsec`` = 0: the noise model belongs to the ``leo`` trajectory).
* The world's checks apply as for ``leo``: the boresight must meet the Earth and the whole image lie on the ground
  (:mod:`.tiles`).
"""

from __future__ import annotations

import numpy as np

from renderlab.errors import UserError

#: the frames a file trajectory may be in, and the names that mean them
FRAMES = {"GCRF": ("GCRF", "GCRS", "ICRF"),
          "ITRF": ("ITRF", "ITRS", "ITRF93", "ITRF97", "ITRF2000", "ITRF2005", "ITRF2008", "ITRF2014", "ITRF2020")}
EARTH_NAMES = ("EARTH", "399")


def _epochs(fp):
    """(epoch of frame 0 as datetime, SI seconds of every frame after it) from the frames' ISO UTC epochs."""
    from astropy.time import Time

    from renderlab.worlds.earth import wgs84

    utc = Time([e.rstrip("Z") for e in fp.epochs_utc], scale="utc")
    return wgs84.parse_epoch(fp.epochs_utc[0]), np.asarray((utc - utc[0]).sec, float)


def _checked(traj, base_dir):
    """The sampled files (:func:`renderlab.trajectory_io.sources.frame_poses`) and their frame, checked."""
    from renderlab.dynamics.camera_paths import check_frame
    from renderlab.trajectory_io.sources import frame_poses

    fp = frame_poses(traj, base_dir, velocities=True)
    if str(fp.frame).strip().upper() in ("J2000", "EME2000"):
        raise UserError(f"trajectory: frame {fp.frame!r} is not GCRF (they differ by the 23 mas frame bias, about a "
                        "metre in LEO); give the states in GCRF or ITRF")
    frame = check_frame(fp, traj, FRAMES, "earth")
    if fp.center is not None and str(fp.center).strip().upper() not in EARTH_NAMES:
        raise UserError(f"trajectory: the Earth world needs geocentric states; the trajectory's centre is "
                        f"{fp.center!r} (use EARTH or 399)")
    if fp.epochs_utc is None:
        raise UserError("trajectory: world.kind 'earth' needs epochs (Earth rotation, the sun): the table has "
                        "relative time_s only; give it an epoch column")
    if fp.velocities_m_s is None:
        raise UserError("trajectory: world.kind 'earth' needs the spacecraft velocity: give at least two samples or "
                        "the velocity columns vx_m_s, vy_m_s, vz_m_s")
    return fp, frame


def file_orbit(scenario, base_dir):
    """The frames of a file trajectory as a :class:`~renderlab.worlds.earth.frame_orbit.FrameOrbit` (module docstring).

    Raises
    ------
    UserError
        A frame the world cannot use, a centre other than the Earth, no epochs, no velocity.
    """
    from renderlab.dynamics.orbits import nadir_attitude
    from renderlab.geometry.camera import CameraModel
    from renderlab.worlds.earth import orientation
    from renderlab.worlds.earth.frame_orbit import FrameOrbit

    traj = scenario.trajectory
    fp, frame = _checked(traj, base_dir)
    epoch, elapsed = _epochs(fp)
    eo = orientation.earth_orientation(epoch, elapsed)
    M = eo.R_itrf_from_gcrf
    p, v = np.asarray(fp.positions_m, float), np.asarray(fp.velocities_m_s, float)
    if frame == "ITRF":
        r = np.einsum("nji,nj->ni", M, p)
        v = np.einsum("nji,nj->ni", M, v + np.cross([0.0, 0.0, orientation.OMEGA_ERA], p))
    else:
        r = p
    if fp.rotations is None:
        R = nadir_attitude(r, v)
    else:
        R = fp.rotations.as_matrix()
        if frame == "ITRF":
            R = np.einsum("nji,njk->nik", M, R)
    source = {"table": traj.file, "ccsds": traj.oem, "spice": "SPICE kernels"}[traj.kind]
    return FrameOrbit(CameraModel.from_dict(scenario.camera.model_dump()), epoch, np.asarray(fp.times_s, float),
                      elapsed, list(fp.epochs_utc), r, v, R, R.copy(), eo, f"file ({traj.kind}: {source}, {frame})",
                      0.0)
