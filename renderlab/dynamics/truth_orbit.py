r"""Truth orbit propagator, of higher fidelity than the onboard filters' models: DOP853 with zonal gravity
J2–J6 or the full EGM2008 field to degree and order 20, optional drag, solar radiation pressure and Sun/Moon
third-body attraction.

The onboard coastline EKF (:mod:`estimators.coastline`) models two-body motion, and
:func:`renderlab.dynamics.orbits.propagate` (fixed-step RK4, two-body + J2) is of the same class. Truth made
by either is the filter's own model; this module is what the truth uses instead when a scenario asks for
``trajectory.truth_model = "zonal_dop853"``.

Theory
------
State :math:`\mathbf x = [\mathbf r, \mathbf v]` in an inertial frame whose Earth pole is :math:`\hat{\mathbf p}`
(GCRF in the Earth world: the ITRF z axis in GCRF per epoch, from :mod:`renderlab.worlds.earth.orientation`).
The pole is always stated: ``TruthForces.pole`` is a vector, nodes in time, or ``"+z"`` for a frame whose z axis
is the Earth's pole (an equator-of-date frame, as the coastline study's ECI); a zonal field without one is refused
(+z in GCRF is off by the precession since J2000, 0.24–1.5 km/day in LEO).

Full field (``TruthForces.harmonics``, ``trajectory.truth_model = "egm2008_dop853"``): EGM2008 to degree and
order ≤ 20 evaluated in ITRF, :math:`\mathbf a = M^\mathsf T\mathbf a_\mathrm{ITRF}(M\mathbf r)` with the Earth
world's GCRF → ITRF rotation M (:mod:`renderlab.dynamics.geopotential`); it needs ``TruthForces.earth_rotation``
(refused without), and the pole of drag is then M's z axis. The tesseral and sectorial terms it adds move a LEO
orbit by 3.5–5 km per day against J2–J6 alone.

Two-body/J2 constants: :mod:`renderlab.dynamics.orbits` (the onboard class, ``j2_rk4``) uses EGM96's J2 =
1.08262668e-3 with GM = 3.986004418e14 m³ s⁻² (WGS-84) and R = 6378137 m; this module uses EGM2008's GM =
3.986004415e14, R = 6378136.3 m and J2 = 1.0826262e-3. From the same state at 1000 km / 45° the two J2 models
drift apart by 1.6 m in a day (``tests/test_geopotential.py`` measures it).

Zonal gravity: :math:`U = \frac{\mu}{r}\big[1 - \sum_{n=2}^{N} J_n (R/r)^n P_n(u)\big]`, :math:`u = \hat{\mathbf r}
\cdot\hat{\mathbf p}`, whose gradient is

.. math:: \mathbf a = -\frac{\mu}{r^2}\hat{\mathbf r} + \frac{\mu}{r^2}\sum_{n=2}^{N} J_n\Big(\frac{R}{r}\Big)^n
          \Big[\big((n+1)P_n + u P_n'\big)\hat{\mathbf r} - P_n'\,\hat{\mathbf p}\Big]

(Legendre :math:`nP_n = (2n-1)uP_{n-1} - (n-1)P_{n-2}`, :math:`P_n' = nP_{n-1} + uP_{n-1}'`; n = 2 is Vallado
eq. 8-30). Coefficients: **EGM2008** (Pavlis, Holmes, Kenyon & Factor 2012, *J. Geophys. Res.* 117, B04406;
tide-free fully normalised :math:`\bar C_{n0}` of the ICGEM ``EGM2008.gfc`` file, GM = 3.986004415e14 m³ s⁻²,
R = 6378136.3 m), unnormalised :math:`J_n = -\sqrt{2n+1}\,\bar C_{n0}`; EGM96 (Lemoine et al. 1998,
NASA/TP-1998-206861) is given too.

Drag (optional): :math:`\mathbf a = -\tfrac12\rho\,C_D\,(A/m)\,|\mathbf v_r|\mathbf v_r`, :math:`\mathbf v_r =
\mathbf v - \omega_\oplus\hat{\mathbf p}\times\mathbf r` (co-rotating atmosphere), ρ from the piecewise
exponential atmosphere of Vallado (*Fundamentals of Astrodynamics and Applications*, 4th ed., Table 8-4) at the
height :math:`h = r - R(1 - f u^2)` above the ellipsoid (≲ 20 m off the geodetic height).

Solar radiation pressure (optional, cannonball): :math:`\mathbf a = P_\odot C_R (A/m)\,(1\,\mathrm{AU}/d)^2\,
\hat{\mathbf d}`, :math:`\mathbf d = \mathbf r - \mathbf r_\odot`, :math:`P_\odot` = 1361 W m⁻² / c, zero in
the Earth's cylindrical shadow.

Third body (optional): :math:`\mathbf a = \mu_b\big[(\mathbf s - \mathbf r)/|\mathbf s - \mathbf r|^3 -
\mathbf s/|\mathbf s|^3\big]` for the Sun and the Moon. Ephemerides: **ERFA** analytic series —
``epv00`` (VSOP2000-based, the Sun to ~ 5 km) and ``moon98`` (Meeus' ELP-2000/82 truncation, the Moon to
~ 10″ / 100 km); both give GCRS axes, evaluated every 30 min and cubic-spline interpolated (the spline error
is ≪ the series' own). They need the epoch (TT); with a non-GCRF study frame their directions are off by that
frame's offset (≤ 0.4° for a mean-of-date frame in 2024).

Integration: ``scipy.integrate.solve_ivp(method="DOP853", rtol=1e-12)`` with atol 1e-6 m on positions and
1e-9 m/s on velocities, landing on every requested time (``t_eval``); any number of states integrate
together as one system.
"""

from __future__ import annotations

from dataclasses import dataclass
from dataclasses import field as dc_field

import numpy as np

from renderlab.dynamics.geopotential import TruncatedField, egm2008
from renderlab.dynamics.orbits import propagate

AU_M = 149597870700.0
C_MPS = 299792458.0
MU_SUN = 1.32712440018e20       # m^3/s^2 (IAU 2009 / DE421)
MU_MOON = 4.9028001e12          # m^3/s^2 (DE421)
OMEGA_EARTH = 7.292115e-5       # rad/s (WGS-84), atmosphere co-rotation
FLATTENING = 1.0 / 298.257223563

#: Vallado Table 8-4: base height (km), density at the base (kg/m^3), scale height (km)
EXPONENTIAL_ATMOSPHERE = np.array([
    (0, 1.225, 7.249), (25, 3.899e-2, 6.349), (30, 1.774e-2, 6.682), (40, 3.972e-3, 7.554),
    (50, 1.057e-3, 8.382), (60, 3.206e-4, 7.714), (70, 8.770e-5, 6.549), (80, 1.905e-5, 5.799),
    (90, 3.396e-6, 5.382), (100, 5.297e-7, 5.877), (110, 9.661e-8, 7.263), (120, 2.438e-8, 9.473),
    (130, 8.484e-9, 12.636), (140, 3.845e-9, 16.149), (150, 2.070e-9, 22.523), (180, 5.464e-10, 29.740),
    (200, 2.789e-10, 37.105), (250, 7.248e-11, 45.546), (300, 2.418e-11, 53.628), (350, 9.518e-12, 53.298),
    (400, 3.725e-12, 58.515), (450, 1.585e-12, 60.828), (500, 6.967e-13, 63.822), (600, 1.454e-13, 71.835),
    (700, 3.614e-14, 88.667), (800, 1.170e-14, 124.64), (900, 5.245e-15, 181.05), (1000, 3.019e-15, 268.00),
])

__all__ = ["ZonalField", "EGM2008", "EGM96", "TruthForces", "zonal_accel", "zonal_potential", "density_exponential",
           "propagate_truth", "forces_from_config", "propagate_for", "TRUTH_MODELS"]

TRUTH_MODELS = ("j2_rk4", "zonal_dop853", "egm2008_dop853")


@dataclass(frozen=True)
class ZonalField:
    """Zonal gravity field: GM (m³/s²), reference radius (m), unnormalised J2, J3, … (tuple)."""

    mu: float
    radius_m: float
    j: tuple[float, ...]
    name: str = ""

    def degree_max(self) -> int:
        return 1 + len(self.j)


def _j_from_normalised(cbar: tuple[float, ...]) -> tuple[float, ...]:
    return tuple(-np.sqrt(2 * n + 1) * c for n, c in enumerate(cbar, start=2))


#: EGM2008 tide-free C̄20 … C̄60 (ICGEM EGM2008.gfc)
EGM2008 = ZonalField(3.986004415e14, 6378136.3, _j_from_normalised(
    (-0.484165143790815e-03, 0.957161207093473e-06, 0.539965866638991e-06, 0.686702913736681e-07,
     -0.149953927978527e-06)), "EGM2008")
#: EGM96 C̄20 … C̄60 (NASA/TP-1998-206861)
EGM96 = ZonalField(3.986004415e14, 6378136.3, _j_from_normalised(
    (-0.484165371736e-03, 0.957254173792e-06, 0.539873863789e-06, 0.685323475630e-07, -0.149957994714e-06)),
    "EGM96")


def _legendre(u: np.ndarray, degree: int) -> tuple[list, list]:
    P, dP = [np.ones_like(u), u], [np.zeros_like(u), np.ones_like(u)]
    for n in range(2, degree + 1):
        P.append(((2 * n - 1) * u * P[n - 1] - (n - 1) * P[n - 2]) / n)
        dP.append(n * P[n - 1] + u * dP[n - 1])
    return P, dP


def _unit_pole(pole) -> np.ndarray:
    """The Earth's pole as a unit vector: ``"+z"`` (the frame's z axis) or a vector; None is refused."""
    if pole is None:
        raise ValueError("the Earth's pole in the propagation frame is not given: pass pole = its direction (GCRF: "
                         "the ITRF z axis of the epoch) or '+z' for a frame whose z axis is the pole")
    p = np.array([0.0, 0.0, 1.0]) if isinstance(pole, str) and pole == "+z" else np.asarray(pole, float)
    return p / np.linalg.norm(p, axis=-1, keepdims=True)


def zonal_accel(r: np.ndarray, field: ZonalField = EGM2008, degree: int = 6, pole=None) -> np.ndarray:
    """Gravity (central + zonal terms J2…J``degree``) at positions r (…, 3); ``pole`` (3,), (…, 3) or ``"+z"``,
    required for ``degree`` ≥ 2 (ValueError without).

    ``degree`` < 2 gives the two-body acceleration alone.
    """
    if degree > field.degree_max():
        raise ValueError(f"zonal_accel: {field.name or 'the field'} has terms up to degree {field.degree_max()}")
    r = np.asarray(r, float)
    rn = np.linalg.norm(r, axis=-1, keepdims=True)
    rh = r / rn
    k = field.mu / rn**2
    a = -k * rh
    if degree >= 2:
        p = _unit_pole(pole)
        u = np.sum(rh * p, -1, keepdims=True)
        P, dP = _legendre(u, degree)
        q = field.radius_m / rn
        for n in range(2, degree + 1):
            c = k * field.j[n - 2] * q**n
            a = a + c * (((n + 1) * P[n] + u * dP[n]) * rh - dP[n] * p)
    return a


def zonal_potential(r: np.ndarray, field: ZonalField = EGM2008, degree: int = 6, pole=None) -> np.ndarray:
    """U = μ/r [1 − Σ Jn (R/r)ⁿ Pn(u)] (m²/s², …) so that the specific energy is ½v² − U (``pole`` as
    :func:`zonal_accel`)."""
    r = np.asarray(r, float)
    rn = np.linalg.norm(r, axis=-1)
    u = np.sum(r * _unit_pole(pole), -1) / rn if degree >= 2 else np.zeros_like(rn)
    P, _ = _legendre(u, max(degree, 1))
    s = np.zeros_like(rn)
    for n in range(2, degree + 1):
        s = s + field.j[n - 2] * (field.radius_m / rn) ** n * P[n]
    return field.mu / rn * (1.0 - s)


def density_exponential(h_m) -> np.ndarray:
    """Atmospheric density (kg/m³) of Vallado's exponential model (Table 8-4) at heights ``h_m`` (m)."""
    h = np.asarray(h_m, float) / 1e3
    i = np.clip(np.searchsorted(EXPONENTIAL_ATMOSPHERE[:, 0], h, side="right") - 1, 0, len(EXPONENTIAL_ATMOSPHERE) - 1)
    h0, rho0, H = EXPONENTIAL_ATMOSPHERE[i].T
    return rho0 * np.exp(-(h - h0) / H)


@dataclass(frozen=True)
class TruthForces:
    """What the truth propagator includes.

    Parameters
    ----------
    field, degree : ZonalField, int
        Gravity field and the highest zonal degree (0 or 1: two-body); with ``harmonics`` the degree of that field.
    harmonics, order : SphericalHarmonics or None, int or None
        The full field (:func:`renderlab.dynamics.geopotential.egm2008`) evaluated in ITRF to ``degree`` and
        ``order`` (default: = degree) instead of the zonal ``field``; needs ``earth_rotation``.
    earth_rotation : EarthRotation or None
        GCRF → ITRF nodes (:class:`renderlab.dynamics.geopotential.EarthRotation`) for ``harmonics``.
    drag, cd : bool, float
        Exponential-atmosphere drag and the drag coefficient.
    srp, cr : bool, float
        Cannonball solar radiation pressure (cylindrical shadow) and the reflectivity coefficient.
    area_to_mass_m2_kg : float
        Cross-section over mass (drag and SRP).
    third_body : bool
        Sun and Moon attraction.
    epoch_tt_jd : (float, float) or None
        Two-part TT Julian date of t = 0 (needed by SRP and third body).
    pole : "+z", (3,), or (t_nodes (M,), poles (M, 3))
        The Earth's pole in the propagation frame: the frame's z axis, fixed, or interpolated linearly in time;
        required by a zonal field of degree ≥ 2 and by drag (None is refused there), taken from
        ``earth_rotation`` with ``harmonics``.
    """

    field: ZonalField = EGM2008
    degree: int = 6
    drag: bool = False
    cd: float = 2.2
    srp: bool = False
    cr: float = 1.3
    area_to_mass_m2_kg: float = 0.01
    third_body: bool = False
    epoch_tt_jd: tuple[float, float] | None = None
    pole: object = dc_field(default=None, compare=False)
    harmonics: object = dc_field(default=None, compare=False)
    order: int | None = None
    earth_rotation: object = dc_field(default=None, compare=False)

    def pole_at(self, t: float) -> np.ndarray:
        if self.earth_rotation is not None and self.harmonics is not None:
            return self.earth_rotation.at(t)[2]
        if self.pole is None or not isinstance(self.pole, tuple):
            return _unit_pole(self.pole)
        tn, pn = self.pole
        return _unit_pole([np.interp(t, tn, pn[:, j]) for j in range(3)])


class _Ephemeris:
    """Geocentric Sun and Moon (m, GCRS axes) over [0, t_end] s after a TT epoch, cubic splines of ERFA series."""

    def __init__(self, epoch_tt_jd: tuple[float, float], t_end: float, step_s: float = 1800.0):
        import erfa
        from scipy.interpolate import CubicSpline

        n = int(np.ceil(t_end / step_s)) + 4
        tn = (np.arange(n) - 1.0) * step_s
        d1, d2 = np.full(n, epoch_tt_jd[0]), epoch_tt_jd[1] + tn / 86400.0
        pvh, _ = erfa.epv00(d1, d2)
        self.sun = CubicSpline(tn, -pvh["p"] * AU_M)
        self.moon = CubicSpline(tn, erfa.moon98(d1, d2)["p"] * AU_M)


def _perturbations(t: float, r: np.ndarray, v: np.ndarray, f: TruthForces, pole: np.ndarray, eph) -> np.ndarray:
    a = np.zeros_like(r)
    rn = np.linalg.norm(r, axis=-1, keepdims=True)
    if f.drag:
        u = np.sum(r * pole, -1, keepdims=True) / rn
        h = rn - f.field.radius_m * (1.0 - FLATTENING * u * u)
        vr = v - np.cross(OMEGA_EARTH * pole, r)
        a = a - 0.5 * density_exponential(h) * f.cd * f.area_to_mass_m2_kg * np.linalg.norm(vr, axis=-1,
                                                                                            keepdims=True) * vr
    if eph is None:
        return a
    s = eph.sun(t)
    if f.srp:
        d = r - s
        dn = np.linalg.norm(d, axis=-1, keepdims=True)
        sh = s / np.linalg.norm(s)
        along = np.sum(r * sh, -1, keepdims=True)
        lit = (along > 0) | (np.linalg.norm(r - along * sh, axis=-1, keepdims=True) > f.field.radius_m)
        p_srp = 1361.0 / C_MPS
        a = a + lit * p_srp * f.cr * f.area_to_mass_m2_kg * (AU_M / dn) ** 2 * d / dn
    if f.third_body:
        for mu_b, sb in ((MU_SUN, s), (MU_MOON, eph.moon(t))):
            d = sb - r
            a = a + mu_b * (d / np.linalg.norm(d, axis=-1, keepdims=True) ** 3 - sb / np.linalg.norm(sb) ** 3)
    return a


def propagate_truth(x0: np.ndarray, t_s: np.ndarray, forces: TruthForces = TruthForces(), *, rtol: float = 1e-12,
                    atol_m: float = 1e-6) -> np.ndarray:
    """Propagate states x0 (…, 6) (at t = 0) to the increasing times ``t_s`` (T,), t_s ≥ 0 → (T, …, 6).

    Parameters
    ----------
    x0 : numpy.ndarray
        [r (m), v (m/s)] in the inertial frame of ``forces.pole``.
    t_s : numpy.ndarray
        Output times (s after t = 0), non-decreasing, ≥ 0.
    forces : TruthForces
    rtol, atol_m : float
        DOP853 tolerances (atol on positions in m; velocities get atol_m × 1e-3 s⁻¹).
    """
    from scipy.integrate import solve_ivp

    t_s = np.asarray(t_s, float)
    x0 = np.asarray(x0, float)
    if t_s.ndim != 1 or np.any(np.diff(t_s) < 0) or (t_s.size and t_s[0] < 0):
        raise ValueError("propagate_truth: times must be non-decreasing and start at or after 0")
    shape = x0.shape
    y0 = x0.reshape(-1, 6)
    t_end = float(t_s[-1]) if t_s.size else 0.0
    if t_end == 0.0:
        return np.broadcast_to(x0, (len(t_s),) + shape).copy()
    needs_eph = forces.srp or forces.third_body
    if needs_eph and forces.epoch_tt_jd is None:
        raise ValueError("propagate_truth: SRP and third-body forces need forces.epoch_tt_jd")
    eph = _Ephemeris(forces.epoch_tt_jd, t_end) if needs_eph else None
    full = _full_field(forces)
    needs_pole = full is None and (forces.degree >= 2 or forces.drag)
    fixed_pole = forces.pole_at(0.0) if needs_pole and not isinstance(forces.pole, tuple) else None

    def rhs(t, y):
        x = y.reshape(-1, 6)
        r, v = x[:, :3], x[:, 3:]
        if full is not None:  # the field in ITRF: a = M^T a_itrf(M r), rows r @ M^T
            M = forces.earth_rotation.at(t)
            pole, a = M[2], full.accel(r @ M.T) @ M
        else:
            pole = fixed_pole if fixed_pole is not None or not needs_pole else forces.pole_at(t)
            a = zonal_accel(r, forces.field, forces.degree, pole)
        if forces.drag or needs_eph:
            a = a + _perturbations(t, r, v, forces, pole, eph)
        return np.concatenate([v, a], -1).ravel()

    atol = np.tile(np.r_[np.full(3, atol_m), np.full(3, atol_m * 1e-3)], len(y0))
    sol = solve_ivp(rhs, (0.0, t_end), y0.ravel(), method="DOP853", t_eval=t_s, rtol=rtol, atol=atol)
    if sol.status != 0:
        raise RuntimeError(f"propagate_truth: DOP853 failed: {sol.message}")
    return sol.y.T.reshape((len(t_s),) + shape)


def _full_field(forces: TruthForces):
    """The truncated full field of ``forces.harmonics`` (None without), refused without the Earth's rotation."""
    if forces.harmonics is None:
        return None
    if forces.earth_rotation is None:
        raise ValueError("propagate_truth: the full field is evaluated in ITRF and needs forces.earth_rotation (the "
                         "GCRF -> ITRF rotation, renderlab.dynamics.geopotential.EarthRotation)")

    return TruncatedField.of(forces.harmonics, forces.degree, forces.order)


def forces_from_config(cfg, epoch_tt_jd=None, pole=None, earth_rotation=None) -> TruthForces:
    """:class:`TruthForces` from a config with ``truth_model``, ``zonal_degree`` (or, for ``"egm2008_dop853"``,
    ``gravity_degree`` and ``gravity_order``), ``drag``, ``srp``, ``third_body``, ``drag_cd``, ``srp_cr``,
    ``area_to_mass_m2_kg`` (missing ones take the defaults); ``pole`` and ``earth_rotation`` as in
    :class:`TruthForces`."""
    d = TruthForces()
    get = lambda name, default: getattr(cfg, name, default)  # noqa: E731
    full = get("truth_model", "zonal_dop853") == "egm2008_dop853"
    harmonics = None
    if full:

        harmonics = egm2008()
    degree = int(get("gravity_degree", 20)) if full else int(get("zonal_degree", d.degree))
    order = get("gravity_order", None) if full else None
    return TruthForces(field=EGM2008, degree=degree, drag=bool(get("drag", False)),
                       cd=float(get("drag_cd", d.cd)), srp=bool(get("srp", False)), cr=float(get("srp_cr", d.cr)),
                       area_to_mass_m2_kg=float(get("area_to_mass_m2_kg", d.area_to_mass_m2_kg)),
                       third_body=bool(get("third_body", False)), epoch_tt_jd=epoch_tt_jd, pole=pole,
                       harmonics=harmonics, order=None if order is None else int(order),
                       earth_rotation=earth_rotation)


def propagate_for(cfg, x0: np.ndarray, t_s: np.ndarray, *, epoch_tt_jd=None, pole=None, earth_rotation=None,
                  rk4_step_s: float = 5.0) -> np.ndarray:
    """Truth states (T, …, 6) at ``t_s`` by ``cfg.truth_model`` (missing: ``"j2_rk4"``).

    ``"j2_rk4"``: :func:`renderlab.dynamics.orbits.propagate` (RK4 two-body, + J2 about the frame's z axis when
    ``cfg.truth_j2`` or ``cfg.j2``; steps ≤ ``rk4_step_s``). ``"zonal_dop853"``: :func:`propagate_truth` with
    :func:`forces_from_config` (``cfg.epoch_tt_jd`` or ``epoch_tt_jd`` for SRP / third body; ``pole`` required:
    a direction, nodes, or ``"+z"``). ``"egm2008_dop853"``: the full field, which needs ``earth_rotation``.

    Raises
    ------
    ValueError
        An unknown model, a zonal model without ``pole``, the full field without ``earth_rotation``.
    """
    model = getattr(cfg, "truth_model", "j2_rk4")
    if model not in TRUTH_MODELS:
        raise ValueError(f"truth_model {model!r}: choose one of {', '.join(TRUTH_MODELS)}")
    if model != "j2_rk4":
        epoch = epoch_tt_jd if epoch_tt_jd is not None else getattr(cfg, "epoch_tt_jd", None)
        return propagate_truth(x0, t_s, forces_from_config(cfg, epoch, pole, earth_rotation))
    j2 = bool(getattr(cfg, "truth_j2", getattr(cfg, "j2", False)))
    return propagate(x0, t_s, j2=j2, max_step_s=rk4_step_s)
