"""The common result of every trajectory reader: a :class:`PoseSeries`, and its sampling at frame times.

Interpolation (documented choice):

* positions, ``"cubic"``: a cubic Hermite spline through the samples and their velocities when the source has
  velocities (OEM, a table with ``vx_m_s``…; the same curve as a SPICE type-13 SPK of degree 3), else a
  not-a-knot cubic spline (scipy ``CubicSpline``); ``"linear"``: piecewise linear.
* attitude: spherical linear interpolation between neighbouring samples (scipy ``Slerp``, the shortest arc; the
  same rotation as a SPICE type-3 CK between two of its quaternions).

At sample times every method returns the sample itself. Times outside the samples are refused, never
extrapolated.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from renderlab.errors import UserError
from renderlab.trajectory_io.timescales import Epoch

#: largest accepted deviation of a quaternion's norm from 1 (then it is normalized)
QUAT_NORM_TOL = 1e-5
_TIME_EPS = 1e-9


@dataclass(frozen=True, eq=False)
class PoseSeries:
    """Camera positions and/or attitudes at increasing times, in one reference frame.

    Attributes
    ----------
    times_s : numpy.ndarray, shape (n,)
        Strictly increasing seconds: after :attr:`epoch0` (TDB seconds) when the source has epochs, else the
        source's own time axis (a table's ``time_s``).
    positions_m : numpy.ndarray, shape (n, 3), or None
        Camera (observer) positions in :attr:`frame`, m; None for an attitude-only source (AEM).
    quat_xyzw : numpy.ndarray, shape (n, 4), or None
        Unit quaternions, scalar last, of ``R_frame_from_cam`` (``v_frame = R·v_cam``, as scipy
        ``Rotation.from_quat``); None for a position-only source (OEM, a table without attitude).
    frame : str
        Name of the reference frame (``SCENE``, ``J2000``, ``IAU_EARTH``…).
    epoch0 : Epoch or None
        The instant of ``times_s = 0``; None when the source carries relative times only.
    velocities_m_s : numpy.ndarray, shape (n, 3), or None
        Velocities in :attr:`frame`, m/s (used by cubic interpolation).
    source : str
        File name (or description) for messages.
    attitude_frame : str or None
        Name of the frame the attitude describes (AEM's other frame, the SPICE camera frame).
    object_name, center_name : str or None
        The observer and the origin of :attr:`frame` as the source names them.
    """

    times_s: np.ndarray
    positions_m: np.ndarray | None
    quat_xyzw: np.ndarray | None
    frame: str
    epoch0: Epoch | None = None
    velocities_m_s: np.ndarray | None = None
    source: str = "trajectory"
    attitude_frame: str | None = None
    object_name: str | None = None
    center_name: str | None = None
    labels: tuple[str, ...] | None = field(default=None, repr=False, compare=False)

    def __post_init__(self):
        t = np.asarray(self.times_s, float)
        if t.ndim != 1 or len(t) == 0:
            raise UserError(f"{self.source}: no samples")
        object.__setattr__(self, "times_s", t)
        if self.positions_m is None and self.quat_xyzw is None:
            raise UserError(f"{self.source}: neither positions nor attitude")
        self._finite(t[:, None], "time")
        bad = np.flatnonzero(np.diff(t) <= 0)
        if len(bad):
            i = int(bad[0]) + 1
            raise UserError(f"{self.source}: time does not increase at {self._label(i)} "
                            f"({self.describe(t[i])} after {self.describe(t[i - 1])})")
        for name in ("positions_m", "velocities_m_s"):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, self._finite(getattr(self, name), name.split("_")[0], 3))
        if self.quat_xyzw is not None:
            q = self._finite(self.quat_xyzw, "quaternion", 4)
            norm = np.linalg.norm(q, axis=1)
            off = np.flatnonzero(np.abs(norm - 1.0) > QUAT_NORM_TOL)
            if len(off):
                i = int(off[0])
                raise UserError(f"{self.source}: the quaternion at {self._label(i)} has norm {norm[i]:.6g}, not 1 "
                                "(check the quaternion order and columns)")
            object.__setattr__(self, "quat_xyzw", q / norm[:, None])

    def _label(self, i: int) -> str:
        return self.labels[i] if self.labels is not None and i < len(self.labels) else f"sample {i + 1}"

    def _finite(self, a, what: str, width: int | None = None) -> np.ndarray:
        a = np.asarray(a, float)
        if width is not None and (a.ndim != 2 or a.shape != (len(self.times_s), width)):
            raise UserError(f"{self.source}: {what} must be {len(self.times_s)}×{width}, got shape {a.shape}")
        rows = np.flatnonzero(~np.isfinite(a).all(axis=1))
        if len(rows):
            raise UserError(f"{self.source}: {what} at {self._label(int(rows[0]))} is not a finite number")
        return a

    # ------------------------------------------------------------------ time
    def describe(self, t: float) -> str:
        """A series time as text: ISO UTC when the source has epochs, else ``12.5 s``."""
        if self.epoch0 is None:
            return f"{t:.9g} s"
        return self.epoch0.plus(t).iso("UTC", 3)

    def coverage(self) -> str:
        """The time span of the samples as text."""
        return f"{self.describe(self.times_s[0])} – {self.describe(self.times_s[-1])}"

    def check_covers(self, t, what: str = "trajectory: frame") -> np.ndarray:
        """``t`` (series times) clipped onto the samples; UserError naming the first time outside them."""
        t = np.asarray(t, float)
        t0, t1 = self.times_s[0], self.times_s[-1]
        tol = _TIME_EPS * max(1.0, abs(t0), abs(t1))
        out = np.flatnonzero((t < t0 - tol) | (t > t1 + tol))
        if len(out):
            k = int(out[0])
            raise UserError(f"{what} {k} at {self.describe(t[k])} is outside {self.source}'s coverage "
                            f"{self.coverage()}")
        return np.clip(t, t0, t1)

    # ------------------------------------------------------------------ sampling
    def positions_at(self, t, method: str = "cubic") -> np.ndarray:
        """Positions (m, shape (len(t), 3)) at series times ``t`` (:mod:`module docstring <.series>`)."""
        from scipy.interpolate import CubicHermiteSpline, CubicSpline

        if self.positions_m is None:
            raise UserError(f"{self.source}: has no positions")
        t = self.check_covers(t)
        ts, p = self.times_s, self.positions_m
        if len(ts) == 1:
            return np.repeat(p, len(t), axis=0)
        if method == "linear":
            return np.stack([np.interp(t, ts, p[:, j]) for j in range(3)], axis=1)
        if method != "cubic":
            raise UserError(f"interpolation must be 'cubic' or 'linear', got {method!r}")
        if self.velocities_m_s is not None:
            return CubicHermiteSpline(ts, p, self.velocities_m_s, axis=0)(t)
        return CubicSpline(ts, p, axis=0)(t)

    def velocities_at(self, t, method: str = "cubic") -> np.ndarray | None:
        """Velocities (m/s, shape (len(t), 3)) at series times ``t``: the time derivative of the curve
        :meth:`positions_at` draws (``linear``: the slope of the segment; a single sample: its own velocity), so
        positions and velocities agree; None for a single sample without a velocity."""
        from scipy.interpolate import CubicHermiteSpline, CubicSpline

        if self.positions_m is None:
            raise UserError(f"{self.source}: has no positions")
        t = self.check_covers(t)
        ts, p, v = self.times_s, self.positions_m, self.velocities_m_s
        if len(ts) == 1:
            return None if v is None else np.repeat(v, len(t), axis=0)
        if method == "linear":
            i = np.clip(np.searchsorted(ts, t, side="right") - 1, 0, len(ts) - 2)
            return (p[i + 1] - p[i]) / (ts[i + 1] - ts[i])[:, None]
        if method != "cubic":
            raise UserError(f"interpolation must be 'cubic' or 'linear', got {method!r}")
        spline = CubicHermiteSpline(ts, p, v, axis=0) if v is not None else CubicSpline(ts, p, axis=0)
        return spline(t, 1)

    def attitude_at(self, t) -> Rotation:
        """``R_frame_from_cam`` at series times ``t`` (SLERP between samples)."""
        from scipy.spatial.transform import Slerp

        if self.quat_xyzw is None:
            raise UserError(f"{self.source}: has no attitude")
        t = self.check_covers(t)
        rots = Rotation.from_quat(self.quat_xyzw)
        if len(self.times_s) == 1:
            return Rotation.from_quat(np.repeat(self.quat_xyzw, len(t), axis=0))
        return Slerp(self.times_s, rots)(t)

    def epochs(self) -> list[Epoch] | None:
        """The epoch of every sample, or None for a relative-time source."""
        return None if self.epoch0 is None else [self.epoch0.plus(float(t)) for t in self.times_s]
