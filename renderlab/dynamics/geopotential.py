r"""The Earth's full gravity field (EGM2008 to degree and order 20) for the truth propagator, evaluated in ITRF.

Theory
------
The geopotential in Earth-fixed coordinates is

.. math:: U = \frac{GM}{r}\sum_{n=0}^{N}\Big(\frac{R}{r}\Big)^n\sum_{m=0}^{n}
          \bar P_{nm}(\sin\varphi)\big(\bar C_{nm}\cos m\lambda + \bar S_{nm}\sin m\lambda\big)

with fully normalised coefficients :math:`\bar C_{nm}, \bar S_{nm}` (Heiskanen & Moritz; :math:`C_{nm} = N_{nm}
\bar C_{nm}`, :math:`N_{nm} = \sqrt{(2 - \delta_{m0})(2n+1)(n-m)!/(n+m)!}`). Its gradient is computed with
Cunningham's recursion of the solid harmonics :math:`V_{nm}, W_{nm}` directly in Cartesian coordinates
(Cunningham 1970, *Celestial Mechanics* 2, 207, doi:10.1007/BF01229495; Montenbruck & Gill, *Satellite Orbits*,
2000, §3.2.4–3.2.5, eqs. 3.29–3.33): no latitude or longitude, so nothing is singular at the poles.

Coefficients: **EGM2008** (Pavlis, Holmes, Kenyon & Factor 2012, *J. Geophys. Res.* 117, B04406,
doi:10.1029/2011JB008916), tide-free, GM = 3.986004415e14 m³ s⁻², R = 6378136.3 m, degree and order ≤ 20 in
``renderlab/dynamics/data/egm2008_n20.csv`` (from the ICGEM ``EGM2008.gfc``). Its zonal terms are the
:data:`renderlab.dynamics.truth_orbit.EGM2008` J2–J6.

Earth orientation: the field rotates with the ITRF. The Earth world hands the propagator the GCRF → ITRF
rotations :math:`M_k` of its own Earth orientation (:mod:`renderlab.worlds.earth.orientation`: IAU 2006/2000A,
IERS EOP) at nodes every ``node_step_s``; between nodes :math:`M(t) = R_3(\omega_\oplus (t - t_k))\,M_k` from the
nearest node (the Earth rotation angle rate; what it leaves out, polar motion times ω⊕Δt and the precession-
nutation drift over ≤ 30 s, is ≲ 10⁻⁹ rad). The acceleration in GCRF is :math:`M^\mathsf T\,\mathbf a_\mathrm{ITRF}
(M\mathbf r)`. Checked against pyshtools (``MakeGravGridPoint``) and an independent propagation in
``tests/test_geopotential.py``.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from math import factorial
from pathlib import Path

import numpy as np

__all__ = ["SphericalHarmonics", "TruncatedField", "egm2008", "EarthRotation", "harmonic_accel"]

TABLE = Path(__file__).resolve().parent / "data" / "egm2008_n20.csv"


@dataclass(frozen=True)
class SphericalHarmonics:
    """A gravity field: GM (m³/s²), reference radius (m), fully normalised ``C``, ``S`` ((N+1, N+1), [n, m])."""

    mu: float
    radius_m: float
    C: np.ndarray
    S: np.ndarray
    name: str = ""

    @property
    def degree_max(self) -> int:
        return self.C.shape[0] - 1

    def unnormalised(self, degree: int, order: int) -> tuple[np.ndarray, np.ndarray]:
        """(C, S) unnormalised, truncated to ``degree`` and ``order`` (shape (degree+1, degree+1))."""
        if not 0 <= order <= degree <= self.degree_max:
            raise ValueError(f"{self.name or 'the field'}: need 0 <= order <= degree <= {self.degree_max}, got "
                             f"degree {degree}, order {order}")
        n_nm = np.zeros((degree + 1, degree + 1))
        for n in range(degree + 1):
            for m in range(min(n, order) + 1):
                n_nm[n, m] = np.sqrt((2 - (m == 0)) * (2 * n + 1) * factorial(n - m) / factorial(n + m))
        return self.C[:degree + 1, :degree + 1] * n_nm, self.S[:degree + 1, :degree + 1] * n_nm


@functools.lru_cache(maxsize=1)
def egm2008() -> SphericalHarmonics:
    """EGM2008 to degree and order 20 (module docstring), read once from the table shipped with the lab."""
    rows = np.loadtxt(TABLE, delimiter=",", comments="#", skiprows=5)
    n, m = rows[:, 0].astype(int), rows[:, 1].astype(int)
    C, S = np.zeros((n.max() + 1,) * 2), np.zeros((n.max() + 1,) * 2)
    C[n, m], S[n, m] = rows[:, 2], rows[:, 3]
    return SphericalHarmonics(3.986004415e14, 6378136.3, C, S, "EGM2008")


@functools.lru_cache(maxsize=1)
def _kernel():
    """The numba kernel of :func:`harmonic_accel` (compiled once, cached on disk)."""
    import numba

    @numba.njit(cache=True)
    def accel(r, C, S, radius, degree, order):  # pragma: no cover - compiled
        nmax = degree + 1
        out = np.zeros(r.shape)
        V = np.zeros((nmax + 1, nmax + 1))
        W = np.zeros((nmax + 1, nmax + 1))
        for i in range(r.shape[0]):
            x, y, z = r[i, 0], r[i, 1], r[i, 2]
            r2 = x * x + y * y + z * z
            rho, x0, y0, z0 = radius * radius / r2, radius * x / r2, radius * y / r2, radius * z / r2
            V[0, 0], W[0, 0] = radius / np.sqrt(r2), 0.0
            for m in range(nmax + 1):  # Cunningham's recursion (Montenbruck & Gill 3.29-3.31)
                if m > 0:
                    V[m, m] = (2 * m - 1) * (x0 * V[m - 1, m - 1] - y0 * W[m - 1, m - 1])
                    W[m, m] = (2 * m - 1) * (x0 * W[m - 1, m - 1] + y0 * V[m - 1, m - 1])
                if m + 1 <= nmax:
                    V[m + 1, m] = (2 * m + 1) * z0 * V[m, m]
                    W[m + 1, m] = (2 * m + 1) * z0 * W[m, m]
                for n in range(m + 2, nmax + 1):
                    V[n, m] = ((2 * n - 1) * z0 * V[n - 1, m] - (n + m - 1) * rho * V[n - 2, m]) / (n - m)
                    W[n, m] = ((2 * n - 1) * z0 * W[n - 1, m] - (n + m - 1) * rho * W[n - 2, m]) / (n - m)
            ax = ay = az = 0.0
            for n in range(degree + 1):  # Montenbruck & Gill eq. 3.33
                ax -= C[n, 0] * V[n + 1, 1]
                ay -= C[n, 0] * W[n + 1, 1]
                az -= (n + 1) * C[n, 0] * V[n + 1, 0]
                for m in range(1, min(n, order) + 1):
                    c, s, f = C[n, m], S[n, m], 0.5 * (n - m + 2) * (n - m + 1)
                    ax += 0.5 * (-c * V[n + 1, m + 1] - s * W[n + 1, m + 1]) + f * (c * V[n + 1, m - 1]
                                                                                  + s * W[n + 1, m - 1])
                    ay += 0.5 * (-c * W[n + 1, m + 1] + s * V[n + 1, m + 1]) + f * (-c * W[n + 1, m - 1]
                                                                                  + s * V[n + 1, m - 1])
                    az += (n - m + 1) * (-c * V[n + 1, m] - s * W[n + 1, m])
            out[i, 0], out[i, 1], out[i, 2] = ax, ay, az
        return out

    return accel


@dataclass(frozen=True)
class TruncatedField:
    """A field truncated to ``degree`` and ``order`` with its unnormalised coefficients computed once (what the
    propagator evaluates at every step)."""

    field: SphericalHarmonics
    degree: int
    order: int
    C: np.ndarray
    S: np.ndarray

    @classmethod
    def of(cls, field: SphericalHarmonics, degree: int, order: int | None = None) -> "TruncatedField":
        order = degree if order is None else order
        return cls(field, int(degree), int(order), *field.unnormalised(degree, order))

    def accel(self, r_itrf) -> np.ndarray:
        """Gravity (m/s², …, 3) at Earth-fixed positions ``r_itrf`` (m, …, 3), central term included."""
        r = np.asarray(r_itrf, float)
        flat = np.ascontiguousarray(r.reshape(-1, 3))
        a = _kernel()(flat, self.C, self.S, float(self.field.radius_m), self.degree, self.order)
        return (a * (self.field.mu / self.field.radius_m**2)).reshape(r.shape)


def harmonic_accel(r_itrf, field: SphericalHarmonics, degree: int, order: int | None = None) -> np.ndarray:
    """Gravity (m/s², …, 3) of ``field`` to ``degree`` and ``order`` (default: = degree) at Earth-fixed positions
    ``r_itrf`` (m, …, 3), central term included (Cunningham's recursion, Montenbruck & Gill eqs. 3.29–3.33)."""
    return TruncatedField.of(field, degree, order).accel(r_itrf)


@dataclass(frozen=True)
class EarthRotation:
    """GCRF → ITRF rotations ``R_nodes`` (M, 3, 3) at times ``t_nodes`` (M,) (s after the propagation's t = 0),
    turned between nodes at the Earth rotation angle rate ``omega`` (rad/s) from the nearest node (module
    docstring)."""

    t_nodes: np.ndarray
    R_nodes: np.ndarray
    omega: float

    def at(self, t: float) -> np.ndarray:
        """M(t) (3, 3): ``r_itrf = M @ r_gcrf``."""
        k = int(np.clip(np.rint(np.interp(t, self.t_nodes, np.arange(len(self.t_nodes)))), 0, len(self.t_nodes) - 1))
        a = self.omega * (t - float(self.t_nodes[k]))
        c, s = np.cos(a), np.sin(a)
        return np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]]) @ self.R_nodes[k]
