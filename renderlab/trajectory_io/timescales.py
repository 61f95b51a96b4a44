"""Epochs of trajectory files: ISO text in UTC, TAI, TT or TDB ↔ TDB seconds past J2000 (SPICE's "ET").

UTC → TDB follows SPICE's leapseconds kernel (``DELTET``, what ``str2et`` does), so a table, a CCSDS file and a
SPICE kernel that name the same UTC epoch land on the same instant::

    TDB − UTC = ΔAT + 32.184 s + K·sin E,   E = M + EB·sin M,   M = M0 + M1·ET

with ΔAT from :data:`LEAP_SECONDS` (the last leap second is the one of 2017-01-01). An :class:`Epoch` keeps whole
days and seconds apart, so differences of epochs (the frame times) keep nanoseconds even decades from J2000.

Durations (:meth:`Epoch.minus`, :meth:`Epoch.plus`: the frame times, a file's sample times) are SI seconds on the
TT scale — the seconds TAI and UTC count, a leap second aside — so ``12:00:00Z`` plus 3600 s is ``13:00:00Z``
exactly; the instant itself stays TDB seconds past J2000 (:attr:`Epoch.et`, what SPICE takes). TT ↔ TDB is SPICE's
``unitim``: TDB = TT + K·sin E evaluated at TT, inverted by one fixed-point step (≪ 1 ns).
Pure Python (light: the scenario validator imports it).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from datetime import date

from renderlab.errors import UserError

#: (year, month, day, TAI − UTC in s from that day on), as in NAIF's leapseconds kernel
LEAP_SECONDS = (
    (1972, 1, 1, 10), (1972, 7, 1, 11), (1973, 1, 1, 12), (1974, 1, 1, 13), (1975, 1, 1, 14), (1976, 1, 1, 15),
    (1977, 1, 1, 16), (1978, 1, 1, 17), (1979, 1, 1, 18), (1980, 1, 1, 19), (1981, 7, 1, 20), (1982, 7, 1, 21),
    (1983, 7, 1, 22), (1985, 7, 1, 23), (1988, 1, 1, 24), (1990, 1, 1, 25), (1991, 1, 1, 26), (1992, 7, 1, 27),
    (1993, 7, 1, 28), (1994, 7, 1, 29), (1996, 1, 1, 30), (1997, 7, 1, 31), (1999, 1, 1, 32), (2006, 1, 1, 33),
    (2009, 1, 1, 34), (2012, 7, 1, 35), (2015, 7, 1, 36), (2017, 1, 1, 37),
)
DELTA_T_A = 32.184  # TT − TAI, s
K, EB, M0, M1 = 1.657e-3, 1.671e-2, 6.239996, 1.99096871e-7  # SPICE DELTET constants
SYSTEMS = ("UTC", "TAI", "TT", "TDB")
_J2000_ORDINAL = date(2000, 1, 1).toordinal()
_LEAP_ORDINALS = tuple((date(y, m, d).toordinal(), n) for y, m, d, n in LEAP_SECONDS)
_ISO = re.compile(r"(\d{4})-(?:(\d{2})-(\d{2})|(\d{3}))(?:[T ](\d{2}):(\d{2})(?::(\d{2}(?:\.\d*)?))?)?(Z)?")


def _delta_at(ordinal: int) -> int:
    """TAI − UTC (s) on the UTC day with proleptic Gregorian ``ordinal`` (9 s before 1972, as SPICE)."""
    n = 9
    for o, v in _LEAP_ORDINALS:
        if ordinal >= o:
            n = v
    return n


def _periodic(et: float) -> float:
    """TDB − TT (s) at ``et`` (SPICE's K·sin E)."""
    m = M0 + M1 * et
    return K * math.sin(m + EB * math.sin(m))


def _tdb_minus_tt(et: float) -> float:
    """TDB − TT (s) at the instant of TDB ``et``: :func:`_periodic` at its TT, ``et − K·sin E(et)`` (one step of the
    fixed point TT = TDB − K·sin E(TT); the next step moves it by < 1e-12 s)."""
    return _periodic(et - _periodic(et))


@dataclass(frozen=True)
class Epoch:
    """An instant: TDB seconds past J2000 as ``days·86400 + seconds`` (0 ≤ seconds < 86400 after :meth:`plus`)."""

    days: int
    seconds: float

    @property
    def et(self) -> float:
        """TDB seconds past J2000 (SPICE ephemeris time) as one float."""
        return self.days * 86400.0 + self.seconds

    @classmethod
    def from_et(cls, et: float) -> "Epoch":
        """The epoch of ephemeris time ``et`` (TDB seconds past J2000)."""
        days = math.floor(et / 86400.0)
        return cls(int(days), float(et - days * 86400.0))

    def minus(self, other: "Epoch") -> float:
        """``self − other`` in SI seconds on the TT scale (module docstring), without losing the fraction to the
        magnitude of either."""
        return ((self.days - other.days) * 86400.0 + (self.seconds - other.seconds)
                - (_tdb_minus_tt(self.et) - _tdb_minus_tt(other.et)))

    def plus(self, seconds: float) -> "Epoch":
        """The epoch ``seconds`` (SI, on the TT scale) later."""
        q, tt = divmod(self.seconds - _tdb_minus_tt(self.et) + float(seconds), 86400.0)
        days = self.days + int(q)
        q, r = divmod(tt + _periodic(days * 86400.0 + tt), 86400.0)
        return Epoch(days + int(q), float(r))

    def tdb_plus(self, seconds: float) -> "Epoch":
        """The epoch ``seconds`` of TDB later (SPICE's ``et + seconds``)."""
        q, r = divmod(self.seconds + float(seconds), 86400.0)
        return Epoch(self.days + int(q), float(r))

    def iso(self, system: str = "UTC", decimals: int = 3) -> str:
        """ISO text of the epoch in ``system`` (``UTC`` gets a ``Z``); a leap second prints as the next 00:00:00."""
        corr = -_tdb_minus_tt(self.et) if system != "TDB" else 0.0
        if system in ("TAI", "UTC"):
            corr -= DELTA_T_A
        if system == "UTC":
            leap = 37
            for _ in range(2):
                day = self.days + math.floor((self.seconds + corr - leap + 43200.0) / 86400.0)
                leap = _delta_at(day + _J2000_ORDINAL)
            corr -= leap
        q, sod = divmod(round(self.seconds + corr + 43200.0, decimals), 86400.0)
        d = date.fromordinal(self.days + int(q) + _J2000_ORDINAL)
        h, rem = divmod(sod, 3600.0)
        mi, s = divmod(rem, 60.0)
        width = 3 + decimals if decimals else 2
        sec = f"{s:0{width}.{decimals}f}"
        return f"{d.isoformat()}T{int(h):02d}:{int(mi):02d}:{sec}" + ("Z" if system == "UTC" else "")


def parse_epoch(text, system: str = "UTC", what: str = "epoch") -> Epoch:
    """An :class:`Epoch` from ISO text (``2030-01-01T00:00:00.5``, ``2030-001T00:00:00``, ``Z`` only for UTC).

    Parameters
    ----------
    text : str
        The calendar epoch (date, or date and time; seconds may have any number of decimals).
    system : {"UTC", "TAI", "TT", "TDB"}
        The time scale the text is in.
    what : str
        Names the value in error messages.

    Raises
    ------
    UserError
        If the text is not an ISO epoch or the time scale is unknown.
    """
    if system not in SYSTEMS:
        raise UserError(f"{what}: time system {system!r} is not supported (use {', '.join(SYSTEMS)})")
    m = _ISO.fullmatch(str(text).strip())
    if m is None:
        raise UserError(f"{what}: {text!r} is not an ISO epoch (YYYY-MM-DDThh:mm:ss[.fff], {system})")
    year, month, day, doy, hh, mm, ss, zulu = m.groups()
    if zulu and system != "UTC":
        raise UserError(f"{what}: {text!r} has a 'Z' (UTC) but the time system is {system}")
    try:
        if doy is not None:
            ordinal = date(int(year), 1, 1).toordinal() + int(doy) - 1
            if not 1 <= int(doy) <= (366 if date(int(year), 12, 31).timetuple().tm_yday == 366 else 365):
                raise ValueError("day of year out of range")
        else:
            ordinal = date(int(year), int(month), int(day)).toordinal()
    except ValueError as err:
        raise UserError(f"{what}: {text!r} is not a valid date ({err})") from None
    h, mi, s = int(hh or 0), int(mm or 0), float(ss or 0.0)
    if h > 23 or mi > 59 or s >= (61.0 if system == "UTC" else 60.0):
        raise UserError(f"{what}: {text!r} has an impossible time of day")
    days, sec = ordinal - _J2000_ORDINAL, h * 3600.0 + mi * 60.0 + s - 43200.0
    if system in ("UTC", "TAI"):
        sec += DELTA_T_A + (_delta_at(ordinal) if system == "UTC" else 0.0)
    if system != "TDB":
        sec += _periodic(days * 86400.0 + sec)
    return Epoch(days, 0.0).tdb_plus(sec)


def utc_text(value):
    """A scenario's ``epoch_utc``: ISO text, or an unquoted TOML date-time with a zone, → checked ISO UTC text.

    For pydantic ``mode="before"`` validators: raises ValueError (not UserError) so the key is named; None passes.
    """
    from datetime import datetime, timezone

    if value is None:
        return None
    if isinstance(value, datetime):
        if value.tzinfo is None:
            raise ValueError(f"give the epoch in UTC with a Z suffix: {value.isoformat()}")
        value = value.astimezone(timezone.utc).isoformat().replace("+00:00", "Z")
    if not isinstance(value, str):
        raise ValueError(f"expected ISO UTC text, got {type(value).__name__}")
    try:
        parse_epoch(value, "UTC", "epoch_utc")
    except UserError as err:
        raise ValueError(str(err).removeprefix("epoch_utc: ")) from None
    return value


def naif_lsk_text() -> str:
    """A NAIF leapseconds kernel (LSK) built from astropy's leap-second table, for SPICE runs given none.

    The text has NAIF's layout (``naif0012.tls``): the ``DELTET`` constants of this module (``DELTA_T_A``, ``K``,
    ``EB``, ``M``) and ``DELTET/DELTA_AT`` with one ``TAI − UTC, @YYYY-MON-D`` pair per leap second of the IERS
    table astropy ships (``astropy.utils.iers.IERS_LEAP_SECOND_FILE``, from ``astropy-iers-data``: no download).
    SPICE's ``str2et`` with it agrees with astropy's UTC → TT to the nanosecond; its TDB − TT is SPICE's
    two-term model, within 30 µs of astropy's full series (``tests/test_spice_truth.py``).

    Returns
    -------
    str
        The kernel text (``KPL/LSK`` … ``\\begintext``).
    """
    from astropy.utils import iers

    table = iers.LeapSeconds.open(iers.IERS_LEAP_SECOND_FILE)
    months = "JAN FEB MAR APR MAY JUN JUL AUG SEP OCT NOV DEC".split()
    pairs = [f"{int(r['tai_utc'])}, @{int(r['year'])}-{months[int(r['month']) - 1]}-{int(r['day'])}" for r in table]
    return ("KPL/LSK\n\nLeapseconds kernel written by renderlab from astropy's IERS leap-second table "
            f"(expires {table.expires.isot[:10]}).\n\n\\begindata\n\n"
            f"DELTET/DELTA_T_A = {DELTA_T_A}\nDELTET/K = {K:.3E}\nDELTET/EB = {EB:.3E}\n"
            f"DELTET/M = ( {M0!r} {M1!r} )\n\nDELTET/DELTA_AT = ( " + "\n                     ".join(pairs)
            + " )\n\n\\begintext\n")
