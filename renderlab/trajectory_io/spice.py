"""Camera poses from SPICE kernels (``spiceypy``): SPK positions, CK/FK attitude, at the frame epochs.

The kernels (SPK, CK, FK, PCK, LSK, SCLK, or a meta-kernel) are loaded for the call and unloaded after it.
Positions: ``spkpos(observer, et, frame, "NONE", center)`` (geometric, no light time), km → m (``spkezr`` states
when velocities are asked for). Attitude:
``pxform(camera_frame, frame, et)``, the matrix mapping camera-frame coordinates to ``frame`` coordinates
(``R_frame_from_cam``); the camera frame must have the lab's axes (+z boresight, +x right, +y down) or be mounted
with the scenario's ``camera_mount_quat_xyzw``. SPICE interpolates as each kernel's type says (no second
interpolation here). The frame epochs are ``str2et(epoch_utc) + times_s``, so an LSK must be among the kernels.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from renderlab.errors import UserError
from renderlab.trajectory_io.series import PoseSeries
from renderlab.trajectory_io.timescales import Epoch


def _one_line(err) -> str:
    """SPICE's short message and the first sentence of its long one."""
    short = getattr(err, "short", "") or ""
    long = " ".join(str(getattr(err, "long", "") or "").split()).split(". ")[0].rstrip(".")
    return f"{short}: {long}" if long else (short or str(err).strip().splitlines()[0])


def _utc(et: float) -> str:
    return Epoch.from_et(et).iso("UTC", 3)


def _windows(cell) -> str:
    import spiceypy as sp

    spans = [sp.wnfetd(cell, i) for i in range(sp.wncard(cell))]
    return "; ".join(f"{_utc(a)} – {_utc(b)}" for a, b in spans) or "none"


def _loaded(kind: str) -> list[str]:
    import spiceypy as sp

    return [sp.kdata(i, kind)[0] for i in range(sp.ktotal(kind))]


def _spk_coverage(body: int) -> str:
    import spiceypy as sp

    cell = sp.cell_double(20000)
    for f in _loaded("SPK"):
        sp.spkcov(f, body, cell)
    return _windows(cell)


def _ck_coverage(camera_frame: str) -> str:
    import spiceypy as sp

    code = sp.namfrm(camera_frame)
    _, frclass, class_id = sp.frinfo(code)
    cell = sp.cell_double(20000)
    for f in _loaded("CK"):
        ids = [class_id] if frclass == 3 else list(sp.ckobj(f, sp.cell_int(1000)))
        for i in ids:
            try:
                sp.ckcov(f, int(i), False, "INTERVAL", 0.0, "TDB", cell)
            except Exception:  # noqa: BLE001 - an id without an SCLK kernel: no coverage to report
                pass
    return _windows(cell)


def _check_names(observer: str, center: str, frames: dict[str, str]) -> None:
    import spiceypy as sp
    from spiceypy.utils.exceptions import NotFoundError

    for what, name in (("observer", observer), ("center", center)):
        try:
            sp.bods2c(name)
        except NotFoundError:
            raise UserError(f"trajectory.{what}: unknown SPICE body {name!r} (not built in and not defined by the "
                            "loaded kernels)") from None
    for key, name in frames.items():
        if sp.namfrm(name) == 0:
            raise UserError(f"trajectory.{key}: unknown SPICE frame {name!r} (not built in and not defined by the "
                            "loaded FK)")


def _sample(observer, center, frame, camera_frame, ets, labels, velocities: bool = False):
    import spiceypy as sp
    from spiceypy.utils.exceptions import SpiceyError

    pos, quat = np.empty((len(ets), 3)), None if camera_frame is None else np.empty((len(ets), 4))
    vel = np.empty((len(ets), 3)) if velocities else None
    for k, et in enumerate(ets):
        try:
            if velocities:
                state = np.asarray(sp.spkezr(observer, et, frame, "NONE", center)[0]) * 1e3
                pos[k], vel[k] = state[:3], state[3:]
            else:
                pos[k] = np.asarray(sp.spkpos(observer, et, frame, "NONE", center)[0]) * 1e3
        except SpiceyError as err:
            cov = _spk_coverage(sp.bods2c(observer))
            raise UserError(f"trajectory: {labels[k]} at {_utc(et)} is outside the SPK coverage of {observer!r} "
                            f"relative to {center!r} (SPK coverage of {observer!r}: {cov}; {err.short})") from None
        if camera_frame is None:
            continue
        try:
            quat[k] = Rotation.from_matrix(np.asarray(sp.pxform(camera_frame, frame, et))).as_quat()
        except SpiceyError as err:
            raise UserError(f"trajectory: {labels[k]} at {_utc(et)} is outside the CK coverage of {camera_frame!r} "
                            f"in {frame!r} (CK coverage: {_ck_coverage(camera_frame)}; {err.short})") from None
    return pos, quat, vel


def read_spice(kernels, *, observer: str, center: str, frame: str, camera_frame: str | None, epoch_utc: str,
               times_s, velocities: bool = False) -> PoseSeries:
    """Camera positions (and attitude) from SPICE at ``epoch_utc + times_s``.

    Parameters
    ----------
    kernels : list of path
        Kernel files, loaded in order (later ones take precedence, as in SPICE).
    observer, center : str
        SPICE body names or ids: the camera (spacecraft) and the origin of the trajectory frame.
    frame : str
        SPICE name of the trajectory frame (``J2000``, ``IAU_EARTH``, a frame of the FK…).
    camera_frame : str or None
        SPICE frame of the camera; None: positions only.
    epoch_utc : str
        UTC epoch of time 0 (SPICE ``str2et`` syntax; ISO recommended).
    times_s : array_like
        Frame times, seconds after ``epoch_utc``.
    velocities : bool
        Also the observer's velocities (``spkezr`` states instead of ``spkpos`` positions).

    Raises
    ------
    UserError
        Missing kernel, no LSK, unknown body or frame, an epoch outside the kernels' coverage (names the epoch
        and the coverage).
    """
    from renderlab.extras import require

    sp = require("spiceypy", "spice")
    from spiceypy.utils.exceptions import SpiceyError

    paths = [Path(k) for k in kernels]
    for p in paths:
        if not p.is_file():
            raise UserError(f"trajectory.kernels: kernel not found: {p}")
    loaded: list[str] = []
    try:
        for p in paths:
            try:
                sp.furnsh(str(p))
            except SpiceyError as err:
                raise UserError(f"trajectory.kernels: SPICE cannot load {p.name} ({_one_line(err)})") from None
            loaded.append(str(p))
        try:
            et0 = sp.str2et(str(epoch_utc))
        except SpiceyError as err:
            hint = " (no leapseconds kernel (LSK) among trajectory.kernels?)" if "LEAPSECONDS" in str(err.short) else ""
            raise UserError(f"trajectory.epoch_utc: SPICE cannot read {epoch_utc!r}{hint}: {_one_line(err)}") from None
        _check_names(observer, center, {"frame": frame, **({"camera_frame": camera_frame} if camera_frame else {})})
        times = np.asarray(times_s, float)
        labels = [f"frame {k}" for k in range(len(times))]
        pos, quat, vel = _sample(observer, center, frame, camera_frame, et0 + times, labels, velocities)
    finally:
        for f in reversed(loaded):
            sp.unload(f)
    return PoseSeries(times_s=times, positions_m=pos, quat_xyzw=quat, frame=frame, epoch0=Epoch.from_et(et0),
                      velocities_m_s=vel, source="SPICE kernels", attitude_frame=camera_frame, object_name=observer, center_name=center,
                      labels=tuple(labels))
