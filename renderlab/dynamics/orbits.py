r"""Earth orbits: two-body (Straub & Christian eqs. 10-12) and J2, from classical elements, vectorised.

Theory
------
Two-body motion (eq. 10) :math:`\ddot{\mathbf r} = -\mu\,\mathbf r/\|\mathbf r\|^3`; as a first-order system
(eqs. 11-12) :math:`\mathbf x = [\mathbf r, \dot{\mathbf r}]`, :math:`\dot{\mathbf x} = [\dot{\mathbf r},\
-\mu\mathbf r/\|\mathbf r\|^3]`. Its closed form is Kepler's: mean anomaly :math:`M = M_0 + n t`,
:math:`n = \sqrt{\mu/a^3}`, eccentric anomaly from :math:`M = E - e\sin E` (Newton), then the perifocal
state rotated by :math:`R_3(-\Omega) R_1(-i) R_3(-\omega)`.

J2 adds the oblateness acceleration (Vallado eq. 8-30)
:math:`\mathbf a_{J2} = -\tfrac32 J_2 \mu R_e^2/r^5\,[x(1-5z^2/r^2),\ y(1-5z^2/r^2),\ z(3-5z^2/r^2)]`,
whose secular effect on a near-circular orbit is the nodal regression
:math:`\dot\Omega = -\tfrac32 n J_2 (R_e/p)^2 \cos i` (Vallado eq. 9-41), :math:`p = a(1-e^2)`.

Constants: GM = 3.986004418e14 m³ s⁻² (WGS-84), R = 6378137 m and EGM96's J2 = 1.08262668e-3 — the onboard
filters' class of model. The truth propagator :mod:`renderlab.dynamics.truth_orbit` uses EGM2008's GM =
3.986004415e14, R = 6378136.3 m, J2 = 1.0826262e-3: from the same state at 1000 km / 45° the two J2 models drift
apart by 1.6 m in a day (measured in ``tests/test_geopotential.py``), a deliberate truth ≠ model difference.
The J2 term acts about the frame's z axis: the frame must have the Earth's pole on +z (equator of date).

Numerical propagation is classic fixed-step RK4 vectorised over any number of states (rows), so a
Monte Carlo of N runs propagates as one (N, 6) array. The inertial frame is the lab's ECI (equator and
equinox of date, see :mod:`renderlab.worlds.earth.wgs84`). Nadir attitude: camera +z toward the Earth's
centre, image top (−y) along the velocity; a star tracker adds a small rotation with settable σ per axis.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

MU_EARTH = 3.986004418e14  # m^3/s^2 (WGS-84 / EGM96)
R_EARTH = 6378137.0  # m, WGS-84 equatorial radius
J2_EARTH = 1.08262668e-3  # EGM96 unnormalised C20 with sign flipped


@dataclass(frozen=True)
class OrbitElements:
    """Classical elements (SI, radians). ``nu`` is the true anomaly at t = 0."""

    a_m: float
    e: float = 0.0
    i_rad: float = 0.0
    raan_rad: float = 0.0
    argp_rad: float = 0.0
    nu_rad: float = 0.0
    mu: float = MU_EARTH

    @classmethod
    def circular(cls, altitude_m: float, inclination_deg: float, raan_deg: float = 0.0, u_deg: float = 0.0,
                 radius_m: float = R_EARTH) -> "OrbitElements":
        """A circular orbit at ``altitude_m`` above ``radius_m`` (argument of latitude ``u_deg`` at t = 0)."""
        return cls(radius_m + altitude_m, 0.0, np.radians(inclination_deg), np.radians(raan_deg), 0.0,
                   np.radians(u_deg))

    @property
    def mean_motion(self) -> float:
        return float(np.sqrt(self.mu / self.a_m**3))

    @property
    def period_s(self) -> float:
        return 2.0 * np.pi / self.mean_motion

    def state(self, t_s) -> tuple[np.ndarray, np.ndarray]:
        """Two-body (Kepler) position and velocity at times ``t_s`` (any shape) → (…, 3) each."""
        e = self.e
        E0 = 2.0 * np.arctan2(np.sqrt(1 - e) * np.sin(self.nu_rad / 2), np.sqrt(1 + e) * np.cos(self.nu_rad / 2))
        M = E0 - e * np.sin(E0) + self.mean_motion * np.asarray(t_s, float)
        E = solve_kepler(M, e)
        nu = 2.0 * np.arctan2(np.sqrt(1 + e) * np.sin(E / 2), np.sqrt(1 - e) * np.cos(E / 2))
        return state_from_elements(self.a_m, e, self.i_rad, self.raan_rad, self.argp_rad, nu, self.mu)


def solve_kepler(M, e: float, tol: float = 1e-14) -> np.ndarray:
    """Eccentric anomaly E with M = E − e sin E (vectorised Newton, e < 1)."""
    M = np.asarray(M, float)
    E = M + e * np.sin(M) if e < 0.8 else np.pi * np.ones_like(M)
    for _ in range(50):
        dE = (E - e * np.sin(E) - M) / (1.0 - e * np.cos(E))
        E = E - dE
        if np.all(np.abs(dE) < tol):
            break
    return E


def state_from_elements(a, e, i, raan, argp, nu, mu: float = MU_EARTH) -> tuple[np.ndarray, np.ndarray]:
    """Position and velocity (…, 3) from classical elements (arrays broadcast together)."""
    a, e, i, raan, argp, nu = np.broadcast_arrays(*(np.asarray(x, float) for x in (a, e, i, raan, argp, nu)))
    p = a * (1 - e**2)
    r = p / (1 + e * np.cos(nu))
    r_pf = np.stack([r * np.cos(nu), r * np.sin(nu), np.zeros_like(r)], -1)
    k = np.sqrt(mu / p)
    v_pf = np.stack([-k * np.sin(nu), k * (e + np.cos(nu)), np.zeros_like(r)], -1)
    cO, sO, ci, si, cw, sw = np.cos(raan), np.sin(raan), np.cos(i), np.sin(i), np.cos(argp), np.sin(argp)
    Q = np.stack([
        np.stack([cO * cw - sO * sw * ci, -cO * sw - sO * cw * ci, sO * si], -1),
        np.stack([sO * cw + cO * sw * ci, -sO * sw + cO * cw * ci, -cO * si], -1),
        np.stack([sw * si, cw * si, ci], -1),
    ], -2)  # R3(-raan) R1(-i) R3(-argp): perifocal → inertial
    return np.einsum("...ij,...j->...i", Q, r_pf), np.einsum("...ij,...j->...i", Q, v_pf)


def two_body_accel(r: np.ndarray, mu: float = MU_EARTH) -> np.ndarray:
    """Eq. 10: −μ r/|r|³ for r of shape (…, 3)."""
    rn = np.linalg.norm(r, axis=-1, keepdims=True)
    return -mu * r / rn**3


def j2_accel(r: np.ndarray, mu: float = MU_EARTH, j2: float = J2_EARTH, radius_m: float = R_EARTH) -> np.ndarray:
    """J2 perturbing acceleration (Vallado eq. 8-30), r (…, 3) in the equatorial inertial frame."""
    x, y, z = r[..., 0], r[..., 1], r[..., 2]
    r2 = np.sum(r * r, axis=-1)
    rn = np.sqrt(r2)
    k = -1.5 * j2 * mu * radius_m**2 / rn**5
    f = 5.0 * z * z / r2
    return np.stack([k * x * (1 - f), k * y * (1 - f), k * z * (3 - f)], -1)


def derivative(x: np.ndarray, *, j2: bool = False, mu: float = MU_EARTH) -> np.ndarray:
    """Eq. 12 (plus J2 when asked): ẋ for states x of shape (…, 6)."""
    r, v = x[..., :3], x[..., 3:]
    a = two_body_accel(r, mu)
    if j2:
        a = a + j2_accel(r, mu)
    return np.concatenate([v, a], -1)


def propagate(x0: np.ndarray, t_s: np.ndarray, *, j2: bool = False, max_step_s: float = 5.0,
              mu: float = MU_EARTH) -> np.ndarray:
    """Fixed-step RK4 propagation of states x0 (…, 6) to the increasing times ``t_s`` (T,), t_s[0] = 0
    is the epoch of x0. Returns (T, …, 6). Steps never exceed ``max_step_s`` and land on every t_s."""
    t_s = np.asarray(t_s, float)
    x = np.asarray(x0, float).copy()
    out = np.empty((len(t_s),) + x.shape)
    t_prev = 0.0
    for k, t in enumerate(t_s):
        span = t - t_prev
        if span < 0:
            raise ValueError("propagate: times must be increasing and start at or after 0")
        n = int(np.ceil(span / max_step_s - 1e-12)) if span > 0 else 0
        h = span / n if n else 0.0
        for _ in range(n):
            k1 = derivative(x, j2=j2, mu=mu)
            k2 = derivative(x + 0.5 * h * k1, j2=j2, mu=mu)
            k3 = derivative(x + 0.5 * h * k2, j2=j2, mu=mu)
            k4 = derivative(x + h * k3, j2=j2, mu=mu)
            x = x + (h / 6.0) * (k1 + 2 * k2 + 2 * k3 + k4)
        out[k] = x
        t_prev = t
    return out


def j2_nodal_rate(el: OrbitElements, j2: float = J2_EARTH, radius_m: float = R_EARTH) -> float:
    """Secular RAAN rate (rad/s) from J2: −3/2 n J2 (R/p)² cos i (Vallado eq. 9-41)."""
    p = el.a_m * (1 - el.e**2)
    return -1.5 * el.mean_motion * j2 * (radius_m / p) ** 2 * np.cos(el.i_rad)


def raan_of(r: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Right ascension of the ascending node (rad) of states r, v (…, 3)."""
    h = np.cross(r, v)
    return np.arctan2(h[..., 0], -h[..., 1])


def ric_axes(x: np.ndarray) -> np.ndarray:
    """Rows r̂, î, ĉ (radial, in-track ĉ × r̂, cross-track along r × v) of the RIC frame of states x (..., 6) →
    C_ric_from_eci (..., 3, 3)."""
    r, v = x[..., :3], x[..., 3:]
    rh = r / np.linalg.norm(r, axis=-1, keepdims=True)
    h = np.cross(r, v)
    ch = h / np.linalg.norm(h, axis=-1, keepdims=True)
    ih = np.cross(ch, rh)
    return np.stack([rh, ih, ch], axis=-2)


def nadir_attitude(r: np.ndarray, v: np.ndarray) -> np.ndarray:
    """R_frame_from_cam (…, 3, 3) of a nadir camera: +z toward the centre (−r̂), image top (−y) along the
    velocity component perpendicular to the boresight, +x = y × z (lab camera convention)."""
    z = -r / np.linalg.norm(r, axis=-1, keepdims=True)
    vp = v - np.sum(v * z, -1, keepdims=True) * z
    y = -vp / np.linalg.norm(vp, axis=-1, keepdims=True)
    x = np.cross(y, z)
    return np.stack([x, y, z], -1)


def star_tracker_attitude(R_frame_from_cam: np.ndarray, sigma_rad: float, rng: np.random.Generator) -> np.ndarray:
    """Attitude reported by a star tracker: the true R_frame_from_cam (…, 3, 3) times a small rotation
    δθ ~ N(0, σ² I₃) about the camera axes (σ = 0 returns a copy)."""
    R = np.asarray(R_frame_from_cam, float)
    if sigma_rad == 0:
        return R.copy()
    dtheta = rng.normal(0.0, sigma_rad, R.shape[:-2] + (3,))
    return R @ Rotation.from_rotvec(dtheta.reshape(-1, 3)).as_matrix().reshape(R.shape)
