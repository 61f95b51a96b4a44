"""Camera poses from SPICE kernels (``spiceypy``): SPK positions, CK/FK attitude, at the frame epochs.

The kernels (SPK, CK, FK, PCK, LSK, SCLK, or a meta-kernel) are loaded for the call and unloaded after it. The frame
epochs are ``times_s`` SI seconds (TT scale) after ``str2et(epoch_utc)``, each as its TDB for SPICE (within
1.2 µs per hour of ``str2et(epoch_utc) + times_s``: :mod:`renderlab.trajectory_io.timescales`); when no leapseconds kernel is among them, one is written from astropy's
leap-second table (:func:`renderlab.trajectory_io.timescales.naif_lsk_text`) and loaded for the call.

Positions (``aberration``, SPICE's ``abcorr``):

* ``"NONE"`` (default): ``spkpos(observer, et, frame, "NONE", center)``, the geometric position, km → m
  (``spkezr`` states when velocities are asked for);
* ``"LT"`` / ``"LT+S"``: the camera relative to where it *sees* the centre, ``−spkpos(center, et, frame, abcorr,
  observer)``: the centre one light time ``lt`` earlier (SPICE's one Newtonian step: the centre at ``et − |r|/c``;
  within ~v·lt·(v/c) of the converged solution, 6 m at 10⁶ km from the Earth) and, with ``+S``, displaced by the
  stellar aberration of the observer's velocity; a body-fixed ``frame`` is evaluated at ``et − lt`` by SPICE. Light
  time needs every body chained to the solar-system barycentre in the SPKs.

Attitude: ``pxform(camera_frame, frame, et)`` (``pxfrm2`` with the frame at ``et − lt`` under light time), the matrix
mapping camera-frame coordinates to ``frame`` coordinates (``R_frame_from_cam``); the camera frame must have the lab's
axes (+z boresight, +x right, +y down) or be mounted with the scenario's ``camera_mount_quat_xyzw``. SPICE
interpolates as each kernel's type says (no second interpolation here).

Sun (``sun.source = "spice"``, :func:`read_spice_sun`): ``spkpos("SUN", et_c, frame, abcorr, center)`` — the direction
toward the sun from the centre of the scene at the epoch ``et_c`` the camera sees it (``et − lt``; ``et`` for
``NONE``), with the same correction: needs an SPK with the Sun (e.g. a DE ephemeris).

Errors name what is missing: an epoch outside an SPK's coverage (with the coverage), a missing PCK for a body-fixed
frame (``FRAMEDATANOTFOUND``), an unknown body or frame, CK gaps.
"""

from __future__ import annotations

import tempfile
from contextlib import contextmanager
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from renderlab.errors import UserError
from renderlab.extras import require
from renderlab.trajectory_io.series import PoseSeries
from renderlab.trajectory_io.timescales import Epoch, naif_lsk_text


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


ABERRATIONS = ("NONE", "LT", "LT+S")


def _spk_error(err, label: str, et: float, what: str, coverage_of: str | None = None) -> UserError:
    """One line for a failed ``spkpos``/``spkezr``/``pxform``: a missing PCK, else the SPK (or CK) coverage."""
    import spiceypy as sp

    sentence = _one_line(err)
    if err.short == "SPICE(FRAMEDATANOTFOUND)":
        return UserError(f"trajectory: {label} at {_utc(et)}: a body-fixed frame has no orientation data — add the "
                         f"PCK (text .tpc or binary .bpc) to trajectory.kernels ({sentence})")
    if coverage_of is None:
        return UserError(f"trajectory: {label} at {_utc(et)}: {what} ({sentence})")
    cov = _spk_coverage(sp.bods2c(coverage_of))
    return UserError(f"trajectory: {label} at {_utc(et)} is {what} (SPK coverage of {coverage_of!r}: {cov}; "
                     f"{sentence})")


def _state(observer, center, frame, et, abcorr, velocities):
    """(position m, velocity m/s or None, light time s) of the camera relative to the centre (module docstring)."""
    import spiceypy as sp

    if abcorr == "NONE":
        if velocities:
            state, lt = sp.spkezr(observer, et, frame, "NONE", center)
            return np.asarray(state[:3]) * 1e3, np.asarray(state[3:]) * 1e3, 0.0
        return np.asarray(sp.spkpos(observer, et, frame, "NONE", center)[0]) * 1e3, None, 0.0
    if velocities:
        state, lt = sp.spkezr(center, et, frame, abcorr, observer)
        return -np.asarray(state[:3]) * 1e3, -np.asarray(state[3:]) * 1e3, float(lt)
    pos, lt = sp.spkpos(center, et, frame, abcorr, observer)
    return -np.asarray(pos) * 1e3, None, float(lt)


def _sample(observer, center, frame, camera_frame, ets, labels, velocities: bool = False, abcorr: str = "NONE"):
    import spiceypy as sp
    from spiceypy.utils.exceptions import SpiceyError

    pos, quat = np.empty((len(ets), 3)), None if camera_frame is None else np.empty((len(ets), 4))
    vel = np.empty((len(ets), 3)) if velocities else None
    for k, et in enumerate(ets):
        try:
            p, v, lt = _state(observer, center, frame, et, abcorr, velocities)
        except SpiceyError as err:
            raise _spk_error(err, labels[k], et, f"outside the SPK coverage of {observer!r} relative to {center!r}",
                             observer) from None
        pos[k] = p
        if velocities:
            vel[k] = v
        if camera_frame is None:
            continue
        try:
            m = sp.pxform(camera_frame, frame, et) if lt == 0.0 else sp.pxfrm2(camera_frame, frame, et, et - lt)
            quat[k] = Rotation.from_matrix(np.asarray(m)).as_quat()
        except SpiceyError as err:
            if err.short == "SPICE(FRAMEDATANOTFOUND)":
                raise _spk_error(err, labels[k], et, "") from None
            raise UserError(f"trajectory: {labels[k]} at {_utc(et)} is outside the CK coverage of {camera_frame!r} "
                            f"in {frame!r} (CK coverage: {_ck_coverage(camera_frame)}; {err.short})") from None
    return pos, quat, vel


@contextmanager
def _furnished(kernels):
    """Load ``kernels`` (and, without an LSK among them, one from astropy's table) for the block; unload after."""
    import spiceypy as sp
    from spiceypy.utils.exceptions import SpiceyError


    paths = [Path(k) for k in kernels]
    for p in paths:
        if not p.is_file():
            raise UserError(f"trajectory.kernels: kernel not found: {p}")
    loaded: list[str] = []
    with tempfile.TemporaryDirectory(prefix="renderlab_lsk_") as tmp:
        try:
            for p in paths:
                try:
                    sp.furnsh(str(p))
                except SpiceyError as err:
                    raise UserError(f"trajectory.kernels: SPICE cannot load {p.name} ({_one_line(err)})") from None
                loaded.append(str(p))
            if not sp.expool("DELTET/DELTA_AT"):
                lsk = Path(tmp) / "renderlab_astropy.tls"
                lsk.write_text(naif_lsk_text())
                sp.furnsh(str(lsk))
                loaded.append(str(lsk))
            yield sp
        finally:
            for f in reversed(loaded):
                sp.unload(f)


def _et0(sp, epoch_utc) -> float:
    from spiceypy.utils.exceptions import SpiceyError

    try:
        return sp.str2et(str(epoch_utc))
    except SpiceyError as err:
        raise UserError(f"trajectory.epoch_utc: SPICE cannot read {epoch_utc!r}: {_one_line(err)}") from None


def _ets(et0: float, times_s) -> np.ndarray:
    """TDB of the instants ``times_s`` SI seconds (TT scale) after ``et0`` (:meth:`Epoch.plus`)."""
    e0 = Epoch.from_et(et0)
    return np.array([e0.plus(float(t)).et for t in np.asarray(times_s, float)])


def read_spice(kernels, *, observer: str, center: str, frame: str, camera_frame: str | None, epoch_utc: str,
               times_s, velocities: bool = False, aberration: str = "NONE") -> PoseSeries:
    """Camera positions (and attitude) from SPICE at ``epoch_utc + times_s``.

    Parameters
    ----------
    kernels : list of path
        Kernel files, loaded in order (later ones take precedence, as in SPICE); without an LSK among them one is
        written from astropy's leap-second table.
    observer, center : str
        SPICE body names or ids: the camera (spacecraft) and the origin of the trajectory frame.
    frame : str
        SPICE name of the trajectory frame (``J2000``, ``IAU_EARTH``, a frame of the FK…).
    camera_frame : str or None
        SPICE frame of the camera; None: positions only.
    epoch_utc : str
        UTC epoch of time 0 (SPICE ``str2et`` syntax; ISO recommended).
    times_s : array_like
        Frame times, SI seconds (TT scale) after ``epoch_utc``.
    velocities : bool
        Also the observer's velocities (``spkezr`` states instead of ``spkpos`` positions).
    aberration : {"NONE", "LT", "LT+S"}
        SPICE's aberration correction of the positions (module docstring).

    Raises
    ------
    UserError
        Missing kernel, unknown body or frame, a missing PCK, an epoch outside the kernels' coverage (names the
        epoch and the coverage).
    """
    require("spiceypy", "spice")
    if aberration not in ABERRATIONS:
        raise UserError(f"trajectory.aberration must be one of {', '.join(ABERRATIONS)}, got {aberration!r}")
    with _furnished(kernels) as sp:
        et0 = _et0(sp, epoch_utc)
        _check_names(observer, center, {"frame": frame, **({"camera_frame": camera_frame} if camera_frame else {})})
        times = np.asarray(times_s, float)
        labels = [f"frame {k}" for k in range(len(times))]
        pos, quat, vel = _sample(observer, center, frame, camera_frame, _ets(et0, times), labels, velocities,
                                 aberration)
    return PoseSeries(times_s=times, positions_m=pos, quat_xyzw=quat, frame=frame, epoch0=Epoch.from_et(et0),
                      velocities_m_s=vel, source="SPICE kernels", attitude_frame=camera_frame, object_name=observer,
                      center_name=center, labels=tuple(labels))


def read_spice_sun(kernels, *, observer: str, center: str, frame: str, epoch_utc: str, times_s,
                   aberration: str = "NONE") -> np.ndarray:
    """The sun from the scene's centre at every frame: ``spkpos("SUN", et_c, frame, aberration, center)`` in metres.

    ``et_c`` is the epoch the camera sees the centre at (``et − lt``, ``lt`` the one-way light time from the centre to
    ``observer`` under ``aberration``; ``et`` for ``NONE``); arguments as :func:`read_spice`.

    Returns
    -------
    numpy.ndarray, shape (n, 3)
        Position of the sun relative to ``center`` in ``frame`` (its norm: the distance), m.

    Raises
    ------
    UserError
        No SPK with the Sun (or a gap), a missing PCK, and everything :func:`read_spice` refuses.
    """
    require("spiceypy", "spice")
    from spiceypy.utils.exceptions import SpiceyError

    if aberration not in ABERRATIONS:
        raise UserError(f"trajectory.aberration must be one of {', '.join(ABERRATIONS)}, got {aberration!r}")
    with _furnished(kernels) as sp:
        ets = _ets(_et0(sp, epoch_utc), times_s)
        _check_names(observer, center, {"frame": frame})
        out = np.empty((len(ets), 3))
        for k, et in enumerate(ets):
            label = f"frame {k}"
            try:
                lt = _state(observer, center, frame, et, aberration, False)[2]
            except SpiceyError as err:
                raise _spk_error(err, label, et, f"outside the SPK coverage of {observer!r} relative to {center!r}",
                                 observer) from None
            try:
                out[k] = np.asarray(sp.spkpos("SUN", et - lt, frame, aberration, center)[0]) * 1e3
            except SpiceyError as err:
                raise _spk_error(err, label, et, f"sun.source = \"spice\" needs the Sun relative to {center!r} in "
                                 "the SPKs (e.g. a DE ephemeris)") from None
    return out
