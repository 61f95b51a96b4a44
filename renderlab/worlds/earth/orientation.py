r"""Earth orientation for the truth: GCRF ↔ ITRF with ERFA (IAU 2006/2000A, CIO based) and IERS EOP.

Frames
------
GCRF
    Geocentric Celestial Reference Frame: origin at the Earth's centre of mass, axes those of the ICRS
    (fixed to extragalactic radio sources; within 23 mas of the J2000.0 mean equator and equinox). It is the
    lab's inertial frame: every manifest key or function argument spelled ``*_eci`` in the Earth world is GCRF.
CIRS / TIRS
    The intermediate frames of the CIO-based chain: the celestial intermediate pole and origin of date (CIRS),
    then the same pole with the terrestrial intermediate origin after the Earth rotation angle (TIRS).
ITRF
    International Terrestrial Reference Frame, Earth-fixed (the WGS-84 ellipsoid of :mod:`.wgs84` lives in it;
    WGS-84 (G2139) and ITRF2014/2020 agree to a few cm). Every ``*_ecef`` key of the Earth world is ITRF.

Theory (IERS Conventions 2010, ch. 5; ERFA ``c2t06a``)
------------------------------------------------------
.. math:: \mathbf r_\mathrm{ITRF} = W(t)^\mathsf T\, R(t)^\mathsf T\, Q(t)^\mathsf T\, \mathbf r_\mathrm{GCRF},
          \qquad R(t)^\mathsf T = R_3(\mathrm{ERA}(UT1))

(IERS Conventions eq. 5.1): Q from the IAU 2006 precession and IAU 2000A nutation (X, Y, s:
``erfa.xys06a``), the Earth rotation angle ERA of UT1 (``erfa.era00``), W the polar motion of the pole
coordinates (x_p, y_p) and the TIO locator s' (``erfa.pom00``, ``erfa.sp00``). This is the chain
``astropy.coordinates`` uses for GCRS → ITRS (the celestial-pole offsets dX, dY, ≤ 0.3 mas = 1 cm on the
ground, are left out by both). Velocities, with M the rotation above: :math:`\mathbf v_\mathrm{ITRF} = M\mathbf v_\mathrm{GCRF} -
\boldsymbol\omega\times\mathbf r_\mathrm{ITRF}`, ω = ω⊕ ẑ (the ERA rate; length-of-day and polar-motion rates,
≤ 1 mm/s at LEO, are left out).

Earth orientation parameters
----------------------------
UT1−UTC and (x_p, y_p) come from astropy's *bundled* IERS tables (package ``astropy-iers-data``: IERS-A
``finals2000A.all`` with the IERS-B ``eopc04`` values laid over it, i.e. ``IERS_Auto`` with downloads off):
importing this module sets ``astropy.utils.iers.conf.auto_download = False``, so nothing is fetched at run
time. Inside the tables' range the values are final (IERS-B) or rapid/predicted (IERS-A, predictions about a
year past the table's date, errors growing to ~10 ms in UT1 = ~5 m on the ground). **Fallback** outside the
range (before 1973, or past the last prediction): UT1−UTC = 0 and no polar motion, with an
:class:`EOPRangeWarning` (errors then up to 0.9 s in UT1 = 400 m and 0.5″ of polar motion = 15 m).
UTC → TT uses astropy's leap-second table (bundled as well; past its end, e.g. decades ahead, ERFA extrapolates
and warns "dubious year").

Everything is vectorised over astropy ``Time`` arrays; results are cached per epoch grid.
"""

from __future__ import annotations

import warnings
from collections import OrderedDict
from dataclasses import dataclass
from datetime import datetime, timezone

import erfa
import numpy as np
from astropy import units as u
from astropy.time import Time, TimeDelta
from astropy.utils import iers

iers.conf.auto_download = False

OMEGA_ERA = 2.0 * np.pi * 1.00273781191135448 / 86400.0  # rad/s, the rate of the Earth rotation angle
_CACHE: OrderedDict = OrderedDict()
_CACHE_SIZE = 32

__all__ = ["EOPRangeWarning", "EarthOrientation", "utc_times", "earth_orientation", "earth_orientation_jd",
           "OMEGA_ERA"]


class EOPRangeWarning(UserWarning):
    """Epochs outside astropy's bundled IERS tables: UT1−UTC = 0 and no polar motion were used there."""


@dataclass(frozen=True)
class EarthOrientation:
    """GCRF → ITRF at N epochs.

    Attributes
    ----------
    time : astropy.time.Time
        The epochs (UTC), shape (N,).
    R_itrf_from_gcrf : numpy.ndarray
        (N, 3, 3) rotations, ``r_itrf = R @ r_gcrf``.
    ut1_minus_utc_s, xp_rad, yp_rad : numpy.ndarray
        (N,) Earth orientation parameters used (zeros where ``eop_in_table`` is False).
    eop_in_table : numpy.ndarray
        (N,) bool: the epoch lies inside the bundled IERS tables.
    """

    time: Time
    R_itrf_from_gcrf: np.ndarray
    ut1_minus_utc_s: np.ndarray
    xp_rad: np.ndarray
    yp_rad: np.ndarray
    eop_in_table: np.ndarray

    @property
    def pole_gcrf(self) -> np.ndarray:
        """(N, 3) the ITRF z axis (the Earth's figure/rotation axis to 0.5″) expressed in GCRF."""
        return self.R_itrf_from_gcrf[:, 2, :]

    def to_itrf(self, r_gcrf, v_gcrf=None):
        """Positions (N, 3) GCRF → ITRF; with velocities also ``(r_itrf, v_itrf)`` (Earth-fixed velocity)."""
        r = np.einsum("nij,nj->ni", self.R_itrf_from_gcrf, np.asarray(r_gcrf, float))
        if v_gcrf is None:
            return r
        v = np.einsum("nij,nj->ni", self.R_itrf_from_gcrf, np.asarray(v_gcrf, float))
        return r, v - np.cross([0.0, 0.0, OMEGA_ERA], r)

    def record(self, k: int) -> dict:
        """JSON-friendly description of epoch k (model, EOP values and their source) for a manifest."""
        return {"model": "IAU 2006/2000A, CIO based (ERFA c2t06a)", "from": "GCRF", "to": "ITRF",
                "ut1_minus_utc_s": float(self.ut1_minus_utc_s[k]),
                "xp_arcsec": float(np.degrees(self.xp_rad[k]) * 3600.0),
                "yp_arcsec": float(np.degrees(self.yp_rad[k]) * 3600.0),
                "eop_source": ("astropy bundled IERS-B/IERS-A" if self.eop_in_table[k]
                               else "none: outside the bundled IERS tables (UT1-UTC = 0, no polar motion)")}


def utc_times(epoch: datetime, t_s) -> Time:
    """UTC ``Time`` array of ``epoch + t_s`` (elapsed SI seconds), kept as two-part Julian dates."""
    t0 = Time(epoch.astimezone(timezone.utc).strftime("%Y-%m-%dT%H:%M:%S.%f"), scale="utc")
    return t0 + TimeDelta(np.atleast_1d(np.asarray(t_s, float)), format="sec")


def _eop(time: Time) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """UT1−UTC (s), x_p, y_p (rad) and an in-table mask from the bundled IERS tables (fallback: zeros + warning)."""
    table = iers.earth_orientation_table.get()
    with iers.conf.set_temp("auto_max_age", None), iers.conf.set_temp("iers_degraded_accuracy", "ignore"):
        dut1, s1 = table.ut1_utc(time, return_status=True)
        xp, yp, s2 = table.pm_xy(time, return_status=True)
    ok = (np.asarray(s1) >= 0) & (np.asarray(s2) >= 0)
    dut1 = np.where(ok, dut1.to_value(u.s), 0.0)
    xp, yp = (np.where(ok, q.to_value(u.rad), 0.0) for q in (xp, yp))
    if not ok.all():
        warnings.warn(f"{int((~ok).sum())} of {ok.size} epochs lie outside astropy's bundled IERS tables "
                      f"({time[~ok][0].isot} ...): UT1-UTC = 0 and no polar motion used there", EOPRangeWarning,
                      stacklevel=3)
    return dut1, xp, yp, ok


def _compute(time: Time) -> EarthOrientation:
    dut1, xp, yp, ok = _eop(time)
    tt = time.tt                                     # (also loads astropy's leap seconds into ERFA)
    ut1a, ut1b = erfa.utcut1(time.jd1, time.jd2, dut1)
    R = erfa.c2t06a(tt.jd1, tt.jd2, ut1a, ut1b, xp, yp)
    return EarthOrientation(time, np.asarray(R, float), dut1, xp, yp, ok)


def _cached(time: Time) -> EarthOrientation:
    key = (np.asarray(time.jd1, float).tobytes(), np.asarray(time.jd2, float).tobytes())
    if key in _CACHE:
        _CACHE.move_to_end(key)
        return _CACHE[key]
    eo = _compute(time)
    _CACHE[key] = eo
    while len(_CACHE) > _CACHE_SIZE:
        _CACHE.popitem(last=False)
    return eo


def earth_orientation(epoch: datetime, t_s) -> EarthOrientation:
    """GCRF → ITRF at ``epoch + t_s`` (all epochs at once; cached per epoch grid).

    Parameters
    ----------
    epoch : datetime
        UTC epoch (timezone-aware, e.g. from :func:`renderlab.worlds.earth.wgs84.parse_epoch`).
    t_s : array_like
        Seconds after the epoch, shape (N,) (a scalar counts as N = 1).

    Returns
    -------
    EarthOrientation
    """
    return _cached(utc_times(epoch, t_s))


def earth_orientation_jd(jd_utc) -> EarthOrientation:
    """:func:`earth_orientation` for Julian dates (UTC) given as floats, any shape flattened to (N,).

    A float Julian date resolves 40 µs (2 cm on the ground); prefer :func:`earth_orientation` with an epoch.
    """
    jd = np.atleast_1d(np.asarray(jd_utc, float)).ravel()
    jd1 = np.floor(jd - 0.5) + 0.5
    return _cached(Time(jd1, jd - jd1, format="jd", scale="utc"))
