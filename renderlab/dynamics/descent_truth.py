r"""True motion of a lander over a spinning small body, in the body-fixed (rotating) frame, with contact detection.

State :math:`\mathbf x = [\mathbf r, \dot{\mathbf r}]` (m, m/s) in the asteroid-fixed frame (``EV5_FIXED``), which
turns at the constant rate ω about its +z axis (:mod:`renderlab.dynamics.small_body`):

.. math::

    \ddot{\mathbf r} = \nabla U(\mathbf r) - 2\,\boldsymbol\omega\times\dot{\mathbf r}
        - \boldsymbol\omega\times(\boldsymbol\omega\times\mathbf r) + \mathbf a_{thrust}   \quad (R1)

(Scheeres, *Orbital Motion in Strongly Perturbed Environments*, Springer 2012, eq. 3.1 for uniform rotation).
The truth gravity U is either

* the polyhedron field of the shape model (:class:`~renderlab.dynamics.polyhedron_gravity.PolyhedronGravity`,
  Werner & Scheeres 1997), or
* a point mass plus J2 about the spin pole, :class:`PointMassJ2`:
  :math:`U = \frac{\mu}{r}\left[1 - J_2\left(\frac{R}{r}\right)^2 P_2(z/r)\right]`,
  :math:`P_2(s) = (3s^2 - 1)/2` (R2; Vallado, *Fundamentals of Astrodynamics and Applications*, 4th ed., eq. 8-30
  for its gradient).

With zero thrust the Jacobi integral :math:`J = \tfrac12|\dot{\mathbf r}|^2 - \tfrac12|\boldsymbol\omega\times
\mathbf r|^2 - U(\mathbf r)` is conserved (R3; Scheeres 2012, ch. 3): the Coriolis term does no work and the
centrifugal term is the gradient of ½|ω×r|².

:meth:`DescentTruth.step` integrates R1 with scipy's DOP853 (Hairer, Nørsett & Wanner 1993) from one control update
to the next with the thrust acceleration held constant (zero-order hold) and stops at contact: a terminal event when
the altitude of the vehicle's reference point above the surface (:class:`ContactSurface`) falls through 0. Near the
landing site the altitude is the height above the site DEM along the site normal (the triangulated DEM the renderer
draws, ``Site.height_at``); elsewhere it is the radial height above the shape mesh (the farthest crossing of the
ray from the body centre through the vehicle). Pure numpy/scipy (the polyhedron field has a compiled point kernel).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from renderlab.dynamics.polyhedron_gravity import PolyhedronGravity
from renderlab.errors import UserError


@dataclass(frozen=True)
class PointMassJ2:
    """Point mass + J2 about body +z (eq. R2)."""

    gm_m3_s2: float
    j2: float = 0.0
    r_ref_m: float = 1.0

    def at(self, r) -> tuple[float, np.ndarray]:
        """(U, ∇U) at ``r`` (3,)."""
        x, y, z = (float(c) for c in r)
        r2 = x * x + y * y + z * z
        rn = math.sqrt(r2)
        mu, k = self.gm_m3_s2, self.j2 * self.r_ref_m**2
        s2 = z * z / r2
        u = mu / rn * (1.0 - k / r2 * 0.5 * (3.0 * s2 - 1.0))
        f = -1.5 * k * mu / rn**5
        a = np.array([-mu * x / rn**3 + f * x * (1 - 5 * s2), -mu * y / rn**3 + f * y * (1 - 5 * s2),
                      -mu * z / rn**3 + f * z * (3 - 5 * s2)])
        return u, a


def make_gravity(kind: str, *, gm_m3_s2: float, j2: float = 0.0, r_ref_m: float = 1.0, vertices=None, faces=None):
    """The truth gravity of ``kind``: ``"point_mass_j2"`` or ``"polyhedron"`` (the mesh scaled to ``gm_m3_s2``)."""
    if kind == "point_mass_j2":
        return PointMassJ2(float(gm_m3_s2), float(j2), float(r_ref_m))
    if kind == "polyhedron":
        if vertices is None or faces is None:
            raise UserError("truth gravity 'polyhedron' needs the shape mesh (vertices and faces)")

        return PolyhedronGravity(vertices, faces, gm_m3_s2=float(gm_m3_s2))
    raise UserError(f"unknown truth gravity '{kind}' (point_mass_j2, polyhedron)")


class ContactSurface:
    """Altitude of a point above the body: the site DEM near the site, the shape mesh elsewhere (module docstring).

    Parameters
    ----------
    vertices, faces : arrays, optional
        A closed shape mesh (body frame, m) containing the body centre, for the radial altitude.
    site : object, optional
        The landing-site DEM: ``origin_m``, ``R_body_from_site`` (columns east, north, up), ``x0_m``, ``cell_m``,
        ``heights_m`` (n, n) and ``height_at(x, y)`` (:class:`renderlab.worlds.ev5.site.Site`).
    """

    def __init__(self, vertices=None, faces=None, site=None):
        if vertices is None and site is None:
            raise UserError("contact surface: give a shape mesh, a site DEM or both")
        self.site = site
        if site is not None:
            self._half = -float(site.x0_m) - float(site.cell_m)   # inside the patch by one cell
            self._o, self._R = np.asarray(site.origin_m, float), np.asarray(site.R_body_from_site, float)
        self.mesh = None
        if vertices is not None:
            v, f = np.asarray(vertices, float), np.asarray(faces, np.int64)
            tri = v[f]
            c = tri.mean(1)
            c /= np.linalg.norm(c, axis=1, keepdims=True)
            vd = tri / np.linalg.norm(tri, axis=2, keepdims=True)
            cos_half = np.einsum("fki,fi->fk", vd, c).min(1)
            # cone around the centroid direction holding the face, widened by 1e-9 rad against rounding
            self.mesh = (tri[:, 0], tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0], c, np.cos(np.arccos(
                np.clip(cos_half, -1, 1)) + 1e-9))
            self.r_max = float(np.linalg.norm(v, axis=1).max())   # the mesh's bounding sphere about the centre

    def site_altitude(self, r) -> float | None:
        """Height above the DEM along the site normal, or None when ``r`` is not over the patch."""
        if self.site is None:
            return None
        s = (np.asarray(r, float) - self._o) @ self._R
        if abs(s[0]) >= self._half or abs(s[1]) >= self._half:
            return None
        return float(s[2] - float(self.site.height_at(s[0], s[1])))

    def mesh_radius(self, u: np.ndarray) -> float:
        """Farthest crossing of the ray from the body centre along the unit vector ``u`` with the mesh, m."""
        a, e1, e2, c, cos_half = self.mesh
        cand = np.flatnonzero(c @ u >= cos_half)
        a, e1, e2 = a[cand], e1[cand], e2[cand]
        p = np.cross(u, e2)
        det = np.einsum("ij,ij->i", e1, p)
        ok = np.abs(det) > 1e-300
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        bu = -np.einsum("ij,ij->i", a, p) * inv
        q = np.cross(-a, e1)
        bv = (q @ u) * inv
        t = np.einsum("ij,ij->i", e2, q) * inv
        eps = 1e-12
        hit = ok & (bu >= -eps) & (bv >= -eps) & (bu + bv <= 1 + eps) & (t > 0)
        if not hit.any():
            raise UserError("contact surface: a ray from the body centre misses the shape mesh (not star-shaped "
                            "about its centre, or not closed)")
        return float(t[hit].max())

    def event_altitude(self, r) -> float:
        """A continuous-where-it-matters function with the sign of the altitude, for contact detection: the altitude
        over the site DEM or, off the site, outside the mesh's bounding sphere the distance to that sphere (a
        positive lower bound of the altitude, without the ray cast), else the altitude."""
        if self.site_altitude(r) is None and self.mesh is not None:
            rn = float(np.linalg.norm(r))
            if rn > self.r_max:
                return rn - self.r_max
        return self.altitude(r)

    def altitude(self, r) -> float:
        """Altitude of ``r`` (3,) above the surface, m (module docstring)."""
        h = self.site_altitude(r)
        if h is not None:
            return h
        if self.mesh is None:
            raise UserError("contact surface: the vehicle left the site DEM and there is no shape mesh")
        r = np.asarray(r, float)
        rn = float(np.linalg.norm(r))
        return rn - self.mesh_radius(r / rn)


@dataclass(frozen=True)
class TruthStep:
    """The state at the end of a step: ``t_s``, ``x`` (6,), ``contact`` (stopped at the surface), ``n_rhs``."""

    t_s: float
    x: np.ndarray
    contact: bool
    n_rhs: int


class DescentTruth:
    """Equation R1 integrated between control updates, with contact (module docstring).

    Parameters
    ----------
    gravity : object
        ``at(r) -> (U, ∇U)``: :class:`PointMassJ2` or a polyhedron field.
    omega_rad_s : float
        Spin rate about body +z, rad/s.
    surface : ContactSurface, optional
        Without one, no contact is detected.
    rtol, atol_m : float
        DOP853 tolerances (position atol in m; velocity atol = atol_m / 100 s).
    """

    def __init__(self, gravity, omega_rad_s: float, surface: ContactSurface | None = None, *, rtol: float = 1e-11,
                 atol_m: float = 1e-9):
        self.gravity, self.surface = gravity, surface
        self.omega = float(omega_rad_s)
        self.rtol = float(rtol)
        self.atol = np.r_[np.full(3, atol_m), np.full(3, atol_m / 100.0)]

    def derivative(self, t: float, x, a_thrust) -> np.ndarray:
        """ẋ of eq. R1."""
        w = self.omega
        _, g = self.gravity.at(x[:3])
        cor = np.array([-2.0 * w * -x[4], -2.0 * w * x[3], 0.0])          # −2 ω×v, ω = (0, 0, w)
        cen = np.array([w * w * x[0], w * w * x[1], 0.0])                  # −ω×(ω×r)
        return np.concatenate([x[3:], g + cor + cen + a_thrust])

    def jacobi(self, x) -> float:
        """J of eq. R3 (m²/s²)."""
        x = np.asarray(x, float)
        u, _ = self.gravity.at(x[:3])
        return 0.5 * float(x[3:] @ x[3:]) - 0.5 * self.omega**2 * float(x[0]**2 + x[1]**2) - u

    def _solve(self, t0: float, x0, t1: float, a_thrust, t_eval=None, contact: bool = True, first_step=None):
        from scipy.integrate import solve_ivp

        a = np.asarray(a_thrust, float).reshape(3)
        events = None
        if contact and self.surface is not None:
            surface = self.surface

            def touch(t, x, _a):
                return surface.event_altitude(x[:3])

            touch.terminal, touch.direction = True, -1.0
            events = touch
        sol = solve_ivp(self.derivative, (float(t0), float(t1)), np.asarray(x0, float), method="DOP853",
                        args=(a,), rtol=self.rtol, atol=self.atol, events=events, t_eval=t_eval,
                        first_step=first_step)
        if sol.status < 0:
            raise UserError(f"truth dynamics: integration failed at t = {sol.t[-1]:.3f} s ({sol.message})")
        return sol

    def step(self, t0: float, x0, t1: float, a_thrust=(0.0, 0.0, 0.0)) -> TruthStep:
        """Integrate from ``t0`` to ``t1`` with the thrust acceleration ``a_thrust`` (m/s², body frame) held;
        stops early at contact (``contact`` True, the state at the touchdown instant)."""
        if not t1 > t0:
            raise UserError(f"truth dynamics: step from {t0} s to {t1} s does not go forward")
        sol = self._solve(t0, x0, t1, a_thrust, first_step=t1 - t0)   # one step when the error allows
        if sol.status == 1:
            return TruthStep(float(sol.t_events[0][0]), np.array(sol.y_events[0][0], float), True, int(sol.nfev))
        return TruthStep(float(sol.t[-1]), np.array(sol.y[:, -1], float), False, int(sol.nfev))

    def coast(self, t0: float, x0, times) -> np.ndarray:
        """States (N, 6) at ``times`` with no thrust and no contact detection (orbits, checks)."""
        times = np.asarray(times, float)
        sol = self._solve(t0, x0, float(times[-1]), np.zeros(3), t_eval=times, contact=False)
        return sol.y.T.copy()
