r"""The sun's direction and distance for UTC epochs, in GCRF (the Earth world's inertial frame), from ERFA.

Theory
------
The Earth's heliocentric and barycentric position and velocity come from ERFA ``epv00`` (VSOP2000-based
analytic series of the IAU SOFA library, ≤ 4.6 km in the Earth's position, 1900–2100), evaluated at TT (TDB −
TT ≤ 1.7 ms is ignored: 0.07 mas of solar motion). The sun as seen from the geocentre is

1. the geometric vector :math:`\mathbf p = -\mathbf r^\mathrm{helio}_\oplus`, corrected for light time
   :math:`\tau = |\mathbf p|/c`: :math:`\mathbf p \leftarrow \mathbf p - \tau\,\mathbf v^\mathrm{bary}_\odot`
   (the sun's barycentric velocity, ≈ 12 m/s; ≤ 0.01″);
2. aberrated by the Earth's barycentric velocity (ERFA ``ab``, annual aberration ≈ 20.5″).

The result is the apparent (proper) direction in GCRS/GCRF axes — the direction sunlight arrives from at the
Earth's centre, which is what shades the ground — and matches astropy's ``get_body("sun", t)`` (GCRS) to
≪ 1″ (``tests/test_earth_orientation.py``). The frame is the one of :mod:`.orientation`; rotate with
:func:`renderlab.worlds.earth.orientation.earth_orientation` for ITRF. Irradiance: the solar constant
1361 W m⁻² (Kopp & Lean 2011) over the squared distance in AU.
"""

from __future__ import annotations

import erfa
import numpy as np

SOLAR_CONSTANT_W_M2 = 1361.0

__all__ = ["SOLAR_CONSTANT_W_M2", "sun_gcrf", "sun_eci", "sun_irradiance"]


def _sun_from_tt(tt1, tt2) -> tuple[np.ndarray, np.ndarray]:
    pvh, pvb = erfa.epv00(tt1, tt2)
    p = -pvh["p"]                                            # au, geocentric sun (geometric)
    v_sun_bary = pvb["v"] - pvh["v"]                         # au/day
    dist = np.linalg.norm(p, axis=-1)
    p = p - (dist / erfa.DC)[..., None] * v_sun_bary         # light time
    n = p / np.linalg.norm(p, axis=-1, keepdims=True)
    v = pvb["v"] / erfa.DC                                   # Earth's barycentric velocity in units of c
    bm1 = np.sqrt(1.0 - np.sum(v * v, -1))
    return np.asarray(erfa.ab(n, v, dist, bm1), float), dist


def sun_gcrf(time) -> tuple[np.ndarray, np.ndarray]:
    """Apparent sun direction (unit vectors, GCRF, (…, 3)) and distance (AU, (…)) at astropy ``Time`` (UTC)."""
    tt = time.tt
    return _sun_from_tt(tt.jd1, tt.jd2)


def sun_eci(jd) -> tuple[np.ndarray, np.ndarray]:
    """(unit vector toward the sun in the lab's ECI = GCRF (…, 3), distance in AU (…)) for Julian date(s) (UTC)."""
    from astropy.time import Time

    jd = np.asarray(jd, float)
    jd1 = np.floor(jd - 0.5) + 0.5
    tt = Time(jd1, jd - jd1, format="jd", scale="utc").tt
    return _sun_from_tt(tt.jd1, tt.jd2)


def sun_irradiance(distance_au) -> np.ndarray:
    """Solar irradiance (W m⁻²) at ``distance_au``."""
    return SOLAR_CONSTANT_W_M2 / np.asarray(distance_au, float) ** 2
