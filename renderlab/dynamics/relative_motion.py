r"""Clohessy-Wiltshire relative motion about a chaser on a circular orbit (Ivanov et al. 2018, eq. 1).

Frame (the paper's orbital frame O, "LVLH" here): origin at the chaser's centre of mass, +x along the
chaser's radius vector (away from the Earth), +z along the orbit normal (angular momentum), +y = z × x
(along-track, the direction of flight). For a circular orbit of mean motion n the linearised relative
motion of the target is (eq. 1)

    ẍ − 2nẏ − 3n²x = 0,   ÿ + 2nẋ = 0,   z̈ + n²z = 0,

whose closed-form state transition matrix :func:`cw_stm` is used here (no numerical integration). The
linearisation error grows like n²|r|²/a · t², negligible for metres of separation over seconds
(a test pins it against a full two-body integration of both satellites).
"""

from __future__ import annotations

import math

import numpy as np

MU_EARTH_M3_S2 = 3.986004418e14
R_EARTH_M = 6378137.0


def mean_motion(altitude_m: float) -> float:
    """Mean motion n (rad/s) of a circular orbit ``altitude_m`` above the equatorial radius."""
    a = R_EARTH_M + float(altitude_m)
    return math.sqrt(MU_EARTH_M3_S2 / a**3)


def cw_stm(n: float, t: float) -> np.ndarray:
    """6×6 state transition matrix of eq. 1: ``[r; v](t) = Φ(t) [r; v](0)`` in the LVLH frame."""
    s, c = math.sin(n * t), math.cos(n * t)
    phi = np.zeros((6, 6))
    # x (radial), y (along-track), z (normal)
    phi[0, :] = [4 - 3 * c, 0, 0, s / n, 2 * (1 - c) / n, 0]
    phi[1, :] = [6 * (s - n * t), 1, 0, -2 * (1 - c) / n, (4 * s - 3 * n * t) / n, 0]
    phi[2, :] = [0, 0, c, 0, 0, s / n]
    phi[3, :] = [3 * n * s, 0, 0, c, 2 * s, 0]
    phi[4, :] = [-6 * n * (1 - c), 0, 0, -2 * s, 4 * c - 3, 0]
    phi[5, :] = [0, 0, -n * s, 0, 0, c]
    return phi


def cw_propagate(state0, n: float, times) -> np.ndarray:
    """Relative states (len(times), 6) = [x, y, z, vx, vy, vz] (m, m/s, LVLH) from ``state0`` at t = 0."""
    x0 = np.asarray(state0, float).reshape(6)
    return np.array([cw_stm(n, float(t)) @ x0 for t in np.asarray(times, float).ravel()])


def sun_in_lvlh(sun_lvlh0, n: float, t: float) -> np.ndarray:
    """An inertially fixed direction seen in the rotating LVLH frame: ``Rz(−n t) · s0`` (unit)."""
    s0 = np.asarray(sun_lvlh0, float)
    c, s = math.cos(n * t), math.sin(n * t)
    out = np.array([c * s0[0] + s * s0[1], -s * s0[0] + c * s0[1], s0[2]])
    return out / np.linalg.norm(out)
