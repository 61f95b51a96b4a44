r"""WGS-84 ellipsoid, geodetic coordinates, local ENU frames, ray–ellipsoid intersection, Earth rotation.

Theory
------
Ellipsoid :math:`(x^2+y^2)/a^2 + z^2/b^2 = 1`, a = 6378137 m, f = 1/298.257223563.
Geodetic → ECEF: :math:`N = a/\sqrt{1-e^2\sin^2\phi}`, :math:`[(N+h)\cos\phi\cos\lambda,\ (N+h)\cos\phi\sin\lambda,\
(N(1-e^2)+h)\sin\phi]`; the inverse uses Bowring's iteration (sub-millimetre after 3 steps in LEO).
A ray :math:`\mathbf o + t\mathbf d` meets the ellipsoid where the quadratic in t of the scaled coordinates
:math:`(x/a, y/a, z/b)` has its smaller positive root.

Frames
------
ECEF
    Earth-fixed: the ITRF (WGS-84 realisations agree with it to a few cm), origin at the geocentre, z the
    IERS reference pole, x the reference meridian. Geodetic coordinates and ENU frames here are in it.
ENU
    East, north, up at a geodetic (lat, lon) — the Earth world's render frame per frame (``ENU_TILE``,
    :mod:`.tiles`), origin on the ellipsoid where the boresight meets it.
ECI
    The lab's inertial frame is the GCRF (see :mod:`.orientation`); :func:`R_ecef_from_eci` is the full
    GCRS → ITRS rotation of IAU 2006/2000A with UT1 and polar motion from astropy's bundled IERS tables
    (:mod:`.orientation` agrees with ``astropy.coordinates`` to < 1 mm on the ground; float Julian dates resolve
    40 µs, 2 cm). The sun (:mod:`.sun`) is in the same GCRF.

:func:`gmst_rad` (IAU 1982 GMST) is *not* used by the truth: it remains for the geometric coastline study's
simplified Earth (a uniform rotation :math:`R_3(\mathrm{GMST}_0 + \omega_\oplus t)` of its own inertial frame);
the onboard estimators carry their own Earth models.
"""

from __future__ import annotations

from datetime import datetime, timezone

import numpy as np

A = 6378137.0
F = 1.0 / 298.257223563
B = A * (1.0 - F)
E2 = F * (2.0 - F)
OMEGA_EARTH = 7.292115e-5  # rad/s (WGS-84)


def geodetic_to_ecef(lat_rad, lon_rad, h_m=0.0) -> np.ndarray:
    """ECEF (…, 3) in metres from geodetic latitude, longitude (rad) and height (m)."""
    lat, lon, h = np.broadcast_arrays(*(np.asarray(v, float) for v in (lat_rad, lon_rad, h_m)))
    s = np.sin(lat)
    N = A / np.sqrt(1.0 - E2 * s * s)
    return np.stack([(N + h) * np.cos(lat) * np.cos(lon), (N + h) * np.cos(lat) * np.sin(lon),
                     (N * (1 - E2) + h) * s], -1)


def ecef_to_geodetic(xyz) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(lat_rad, lon_rad, h_m) from ECEF (…, 3) (Bowring's iteration)."""
    xyz = np.asarray(xyz, float)
    x, y, z = xyz[..., 0], xyz[..., 1], xyz[..., 2]
    p = np.hypot(x, y)
    lon = np.arctan2(y, x)
    ep2 = E2 / (1 - E2)
    lat = np.arctan2(z, p * (1 - E2))
    for _ in range(4):
        beta = np.arctan2((1 - F) * np.sin(lat), np.cos(lat))
        lat = np.arctan2(z + ep2 * B * np.sin(beta) ** 3, p - E2 * A * np.cos(beta) ** 3)
    s = np.sin(lat)
    N = A / np.sqrt(1 - E2 * s * s)
    c = np.cos(lat)
    h = np.where(np.abs(c) > 1e-9, p / np.where(np.abs(c) > 1e-9, c, 1.0) - N, np.abs(z) - B)
    return lat, lon, h


def R_ecef_from_enu(lat_rad, lon_rad) -> np.ndarray:
    """Rotation (…, 3, 3) whose columns are east, north, up at geodetic (lat, lon), in ECEF."""
    lat, lon = np.broadcast_arrays(np.asarray(lat_rad, float), np.asarray(lon_rad, float))
    sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    e = np.stack([-so, co, np.zeros_like(lat)], -1)
    n = np.stack([-sl * co, -sl * so, cl], -1)
    u = np.stack([cl * co, cl * so, sl], -1)
    return np.stack([e, n, u], -1)


def ray_ellipsoid(origin, direction, h_m: float = 0.0) -> np.ndarray:
    """Distance t ≥ 0 along ``origin + t·direction`` (…, 3) to the first hit of the ellipsoid raised by
    ``h_m`` (a, b → a + h, b + h); NaN where the ray misses or starts inside."""
    o = np.asarray(origin, float)
    d = np.asarray(direction, float)
    s = np.array([1.0 / (A + h_m), 1.0 / (A + h_m), 1.0 / (B + h_m)])
    os_, ds = o * s, d * s
    qa = np.sum(ds * ds, -1)
    qb = 2.0 * np.sum(os_ * ds, -1)
    qc = np.sum(os_ * os_, -1) - 1.0
    disc = qb * qb - 4 * qa * qc
    with np.errstate(invalid="ignore"):
        sq = np.sqrt(disc)
        # numerically stable smaller root
        q = -0.5 * (qb + np.copysign(sq, qb))
        t1, t2 = q / qa, qc / q
    t = np.minimum(np.where(t1 > 0, t1, np.inf), np.where(t2 > 0, t2, np.inf))
    return np.where((disc >= 0) & (qc > 0) & np.isfinite(t), t, np.nan)


def parse_epoch(text: str) -> datetime:
    """A UTC epoch from ISO 8601 text ('2024-03-20T12:00:00Z'); naive times are taken as UTC."""
    dt = datetime.fromisoformat(text.replace("Z", "+00:00"))
    return dt.replace(tzinfo=timezone.utc) if dt.tzinfo is None else dt.astimezone(timezone.utc)


def julian_date(epoch: datetime, t_s=0.0) -> np.ndarray:
    """Julian date (UTC) of ``epoch + t_s`` seconds."""
    epoch = epoch.astimezone(timezone.utc)
    j2000 = datetime(2000, 1, 1, 12, tzinfo=timezone.utc)
    return 2451545.0 + ((epoch - j2000).total_seconds() + np.asarray(t_s, float)) / 86400.0


def gmst_rad(jd_ut1) -> np.ndarray:
    """Greenwich mean sidereal time (IAU 1982) in radians for Julian date(s) (UT1); not the truth's rotation."""
    d = np.asarray(jd_ut1, float) - 2451545.0
    T = d / 36525.0
    deg = 280.46061837 + 360.98564736629 * d + 0.000387933 * T**2 - T**3 / 38710000.0
    return np.radians(np.mod(deg, 360.0))


def R_ecef_from_eci(jd_utc) -> np.ndarray:
    """Rotation (…, 3, 3) GCRF → ITRF (:mod:`.orientation`) for Julian date(s) (UTC) given as floats."""
    from renderlab.worlds.earth.orientation import earth_orientation_jd

    jd = np.asarray(jd_utc, float)
    return earth_orientation_jd(jd).R_itrf_from_gcrf.reshape(jd.shape + (3, 3))
