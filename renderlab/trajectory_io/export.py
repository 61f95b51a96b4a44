"""A truth set's camera poses back to the user's tools: a :class:`PoseSeries`, an OEM and an AEM.

Reads ``manifest.json`` directly (frame ``time_s``, ``pose.position_m``, ``pose.quat_render_from_cam_xyzw``,
``render_frame``: its ``name`` and the ``source_frame``/``source_center``/``source_object`` a file trajectory's set
records; the Earth world's per-frame ``spacecraft`` GCRF states instead of its per-frame ENU tiles), so it needs neither the renderer nor the truth-set reader. Epochs: the first frame's
``epoch_utc`` when the manifest has one, else ``epoch_utc`` given here (the epoch of ``time_s = 0``), else the
scenario's ``trajectory.epoch_utc``; later frames follow by their ``time_s`` (TDB seconds, as everywhere in
:mod:`renderlab.trajectory_io`). Without an epoch the series keeps relative times (CCSDS needs one).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from renderlab.errors import UserError
from renderlab.inputs import epoch_text, read_json, short, shown
from renderlab.trajectory_io.ccsds import write_aem, write_oem
from renderlab.trajectory_io.series import PoseSeries
from renderlab.trajectory_io.timescales import parse_epoch


def _manifest(folder: Path) -> dict:
    """The truth set's ``manifest.json`` (a regular JSON file of bounded size; ``renderlab export`` has validated it
    with :class:`renderlab.contracts.file_models.TruthManifest` through :meth:`renderlab.files.truthset.TruthSet.open`)."""
    p = Path(folder) / "manifest.json"
    if not p.is_file():
        raise UserError(f"not a truth set (no manifest.json): {shown(folder)}")
    m = read_json(p, "truth-set manifest")
    if not isinstance(m, dict):
        raise UserError(f"truth-set manifest {shown(p)} must be a JSON object")
    return m


def kvn_text(value, what: str, max_len: int = 80) -> str:
    """A value for a CCSDS KVN line: 1..``max_len`` printable ASCII characters (KVN has no escapes: a newline or
    control character would start a line of its own and break the message)."""
    if not isinstance(value, str) or not value.strip() or len(value) > max_len \
            or any(not (" " <= c <= "~") for c in value):
        raise UserError(f"{what} must be 1..{max_len} printable ASCII characters (no newline or control "
                        f"character), got {short(value)}")
    return value


def truthset_pose_series(folder, epoch_utc: str | None = None) -> PoseSeries:
    """The camera poses of a truth set's frames (module docstring), frames in time order.

    Parameters
    ----------
    folder : path
        The truth set folder.
    epoch_utc : str, optional
        UTC epoch of ``time_s = 0`` when the frames carry no ``epoch_utc``.
    """
    m = _manifest(Path(folder))
    try:
        frames = sorted(m.get("frames") or [], key=lambda f: float(f["time_s"]))
        if not frames:
            raise UserError(f"{shown(folder)}: the truth set has no frames")
        times = np.array([float(f["time_s"]) for f in frames])
        pos = np.array([f["pose"]["position_m"] for f in frames], float).reshape(len(frames), 3)
        quat = np.array([f["pose"]["quat_render_from_cam_xyzw"] for f in frames], float).reshape(len(frames), 4)
    except (KeyError, TypeError, ValueError, AttributeError) as err:
        raise UserError(f"{shown(folder)}: a frame has no usable time and pose ({short(str(err))})") from None
    epoch0 = None
    if frames[0].get("epoch_utc"):  # the first frame's epoch; the others by their (exact) time_s
        epoch0 = parse_epoch(frames[0]["epoch_utc"], "UTC", "manifest epoch_utc")
    else:
        given = epoch_utc or ((m.get("scenario") or {}).get("trajectory") or {}).get("epoch_utc")
        if given:
            given = epoch_text(given, "epoch_utc")
            epoch0 = parse_epoch(given, "UTC", "epoch_utc").plus(times[0])
    if epoch0 is not None:
        times = times - times[0]
    names, vel = _names(m), None
    inertial = _inertial_states(frames, folder)
    if inertial is not None:
        pos, vel, quat, names = inertial
    return PoseSeries(times_s=times, positions_m=pos, quat_xyzw=quat, frame=names["frame"], epoch0=epoch0,
                      velocities_m_s=vel, source=Path(folder).name, attitude_frame="CAMERA",
                      object_name=names.get("object"), center_name=names.get("center"),
                      labels=tuple(f"frame {f.get('index', i)}" for i, f in enumerate(frames)))


def _names(m: dict) -> dict:
    """The frame, origin and camera body the set was made in: the render frame's ``source_*`` names (a file
    trajectory in the analytic world), else the scenario's SPICE/CCSDS names, else the render frame's name."""
    rf = m.get("render_frame") if isinstance(m.get("render_frame"), dict) else {}
    traj = ((m.get("scenario") or {}).get("trajectory") or {})
    names = {"frame": rf.get("name") or "SCENE"}
    if rf.get("name", "SCENE") == "SCENE" and traj.get("kind") in ("spice", "ccsds", "table"):
        names.update({k: traj[key] for k, key in (("frame", "frame"), ("center", "center"), ("object", "observer"))
                      if isinstance(traj.get(key), str) and traj[key]})
    names.update({k: rf[f"source_{k}"] for k in ("frame", "center", "object") if isinstance(rf.get(f"source_{k}"), str)})
    return names


def _inertial_states(frames: list, folder):
    """Earth-world frames (a per-frame ENU tile as render frame): the true GCRF states and attitude from each frame's
    ``spacecraft`` record, ``(r, v, q_eci_from_cam, names)``; None for other worlds."""
    from scipy.spatial.transform import Rotation

    if not all(isinstance(f.get("spacecraft"), dict) and "r_eci_m" in f["spacecraft"] for f in frames):
        return None
    try:
        sc = [f["spacecraft"] for f in frames]
        r = np.array([s["r_eci_m"] for s in sc], float).reshape(len(sc), 3)
        v = np.array([s["v_eci_mps"] for s in sc], float).reshape(len(sc), 3)
        M = np.array([s["R_ecef_from_eci"] for s in sc], float).reshape(len(sc), 3, 3)
        R_ecef_cam = Rotation.from_quat(np.array([s["quat_ecef_from_cam_xyzw"] for s in sc], float)).as_matrix()
    except (KeyError, TypeError, ValueError) as err:
        raise UserError(f"{shown(folder)}: a frame's spacecraft record is unusable ({short(str(err))})") from None
    q = Rotation.from_matrix(np.einsum("nji,njk->nik", M, R_ecef_cam)).as_quat()
    frame = (frames[0].get("frames") or {}).get("inertial") or "GCRF"
    return r, v, q, {"frame": frame, "center": "EARTH"}


def export_truthset(folder, *, oem=None, aem=None, epoch_utc: str | None = None, object_name: str | None = None,
                    center_name: str | None = None, **kwargs) -> PoseSeries:
    """Write a truth set's camera poses as a KVN OEM and/or AEM (paths ``oem``, ``aem``); returns the series.

    The messages keep the names the set was made in (:func:`truthset_pose_series`): ``REF_FRAME`` the trajectory's
    frame (a SPICE or OEM frame, ``GCRF`` for the Earth world, else the render frame's name), ``CENTER_NAME`` its
    origin (default ``ORIGIN`` when the set has none), ``OBJECT_NAME`` the camera's body (default ``CAMERA``);
    ``object_name`` / ``center_name`` override them. ``kwargs`` go to :func:`~renderlab.trajectory_io.ccsds.
    write_oem` / ``write_aem`` (``time_system``, ``creation_date``, ``originator``, …; AEM-only
    ``attitude_dir``/``quaternion_type``).
    """
    series = truthset_pose_series(folder, epoch_utc)
    object_name = kvn_text(object_name or series.object_name or "CAMERA", "--object-name")
    center_name = kvn_text(center_name or series.center_name or "ORIGIN", "center name")
    kvn_text(series.frame, "the set's frame name")
    if series.epoch0 is None and (oem or aem):
        raise UserError(f"{folder}: frames have relative times only; give epoch_utc to write CCSDS messages")
    aem_only = {"attitude_dir", "quaternion_type", "camera_frame"}
    if oem:
        write_oem(oem, series, object_name=object_name, center_name=center_name,
                  **{k: v for k, v in kwargs.items() if k not in aem_only})
    if aem:
        write_aem(aem, series, object_name=object_name, **kwargs)
    return series
