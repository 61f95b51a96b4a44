r"""The sun's direction for a UTC epoch (Astronomical Almanac low-precision formula).

Theory (Astronomical Almanac, section C "Low precision formulas for the Sun"): with n = JD − 2451545.0,
mean longitude L = 280.460° + 0.9856474° n, mean anomaly g = 357.528° + 0.9856003° n, ecliptic longitude
λ = L + 1.915° sin g + 0.020° sin 2g, obliquity ε = 23.439° − 0.0000004° n, distance
R = 1.00014 − 0.01671 cos g − 0.00014 cos 2g AU. Unit vector (equator/equinox of date):
(cos λ, cos ε sin λ, sin ε sin λ). Stated accuracy 0.01° in direction for 1950–2050; the irradiance is
the solar constant 1361 W m⁻² / R².
"""

from __future__ import annotations

import numpy as np

SOLAR_CONSTANT_W_M2 = 1361.0


def sun_eci(jd) -> tuple[np.ndarray, np.ndarray]:
    """(unit vector toward the sun in the lab ECI (…, 3), distance in AU (…)) for Julian date(s)."""
    n = np.asarray(jd, float) - 2451545.0
    L = np.radians(280.460 + 0.9856474 * n)
    g = np.radians(357.528 + 0.9856003 * n)
    lam = L + np.radians(1.915) * np.sin(g) + np.radians(0.020) * np.sin(2 * g)
    eps = np.radians(23.439 - 0.0000004 * n)
    R = 1.00014 - 0.01671 * np.cos(g) - 0.00014 * np.cos(2 * g)
    u = np.stack([np.cos(lam), np.cos(eps) * np.sin(lam), np.sin(eps) * np.sin(lam)], -1)
    return u, R


def sun_irradiance(distance_au) -> np.ndarray:
    """Solar irradiance (W m⁻²) at ``distance_au``."""
    return SOLAR_CONSTANT_W_M2 / np.asarray(distance_au, float) ** 2
