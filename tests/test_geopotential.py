"""The full EGM2008 field (degree and order 20) of the truth propagator, against an independent implementation.

Before the change the Earth truth had zonal terms J2–J6 only (``"egm2008_dop853"`` did not exist) and a zonal field
without a pole silently used +z. Oracles: pyshtools' ``MakeGravGridPoint`` (SHTOOLS' Fortran, spherical coordinates,
4π-normalised Legendre functions) for the acceleration; for one day in LEO an independent propagation — scipy's
DOP853 on pyshtools' gravity rotated with ERFA's ``c2t06a`` at every step (IERS EOP from astropy) — against the
Earth world's own (Cunningham's recursion, rotation nodes every minute)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from renderlab.dynamics import orbits
from renderlab.dynamics.geopotential import egm2008, harmonic_accel
from renderlab.dynamics.truth_orbit import EGM2008, TruthForces, ZonalField, propagate_truth, zonal_accel

pysh = pytest.importorskip("pyshtools")
REPO = Path(__file__).resolve().parents[1]


def _pysh_accel(cilm, field, r, lmax):
    """pyshtools' gravity at an Earth-fixed point, (r, θ, φ) components → Cartesian."""
    rn = float(np.linalg.norm(r))
    lat, lon = math.degrees(math.asin(r[2] / rn)), math.degrees(math.atan2(r[1], r[0]))
    g = pysh.gravmag.MakeGravGridPoint(cilm, field.mu, field.radius_m, rn, lat, lon, lmax=lmax)
    th, ph = math.radians(90.0 - lat), math.radians(lon)
    e_r = [math.sin(th) * math.cos(ph), math.sin(th) * math.sin(ph), math.cos(th)]
    e_t = [math.cos(th) * math.cos(ph), math.cos(th) * math.sin(ph), -math.sin(th)]
    e_p = [-math.sin(ph), math.cos(ph), 0.0]
    return g[0] * np.array(e_r) + g[1] * np.array(e_t) + g[2] * np.array(e_p)


def _cilm(field, degree, order):
    cilm = np.zeros((2, degree + 1, degree + 1))
    cilm[0], cilm[1] = field.C[:degree + 1, :degree + 1], field.S[:degree + 1, :degree + 1]
    cilm[:, :, order + 1:] = 0.0
    return cilm


@pytest.mark.parametrize("degree, order", [(20, 20), (12, 8), (6, 0)])
def test_acceleration_matches_pyshtools(degree, order):
    f = egm2008()
    rng = np.random.default_rng(20)
    lat = np.radians(rng.uniform(-88.0, 88.0, 40))
    lon = rng.uniform(-np.pi, np.pi, 40)
    rad = rng.uniform(6.5e6, 4.2e7, 40)
    r = np.stack([rad * np.cos(lat) * np.cos(lon), rad * np.cos(lat) * np.sin(lon), rad * np.sin(lat)], 1)
    ours = harmonic_accel(r, f, degree, order)
    ref = np.array([_pysh_accel(_cilm(f, degree, order), f, p, degree) for p in r])
    rel = np.linalg.norm(ours - ref, axis=1) / np.linalg.norm(ref, axis=1)
    print(f"degree {degree} order {order}: max |Δa|/|a| = {rel.max():.1e}")
    assert rel.max() < 1e-13


def test_the_table_is_egm2008_and_its_zonal_part_is_the_zonal_truth():
    """The shipped table's C̄n0 are the truth propagator's EGM2008 J2–J6; order 0 is its zonal field about +z, also at
    the poles, where the Cartesian recursion has no singularity."""
    f = egm2008()
    assert f.degree_max == 20 and f.C[0, 0] == 1.0 and f.mu == EGM2008.mu and f.radius_m == EGM2008.radius_m
    assert np.allclose([-math.sqrt(2 * n + 1) * f.C[n, 0] for n in range(2, 7)], EGM2008.j, rtol=1e-14, atol=0)
    assert (f.C[2, 2], f.S[2, 2]) == (0.243938357328313e-05, -0.140027370385934e-05)
    r = np.array([[7.0e6, 1.0e5, -2.0e6], [0.0, 0.0, 7.2e6], [0.0, 0.0, -6.9e6], [1.0, -3.0, 8.0e6]])
    a = harmonic_accel(r, f, 6, 0)
    assert np.abs(a - zonal_accel(r, EGM2008, 6, "+z")).max() < 1e-15 * 10.0
    with pytest.raises(ValueError, match="pole in the propagation frame is not given"):
        zonal_accel(r, EGM2008, 6)
    with pytest.raises(ValueError, match="needs forces.earth_rotation"):
        propagate_truth(np.r_[r[0], 0.0, 7.5e3, 0.0], np.array([0.0, 60.0]), TruthForces(harmonics=f, degree=20))


def _oracle(x0, t_out, epoch, eo):
    """DOP853 on pyshtools' gravity, rotated GCRF → ITRF by erfa.c2t06a at every evaluation (EOP interpolated)."""
    import erfa
    from scipy.integrate import solve_ivp

    f = egm2008()
    cilm = _cilm(f, 20, 20)
    tt, utc = eo.time.tt, eo.time
    t_nodes = np.asarray((utc - utc[0]).sec)

    def rot(t):
        dut1, xp, yp = (np.interp(t, t_nodes, v) for v in (eo.ut1_minus_utc_s, eo.xp_rad, eo.yp_rad))
        ut1a, ut1b = erfa.utcut1(utc[0].jd1, utc[0].jd2 + t / 86400.0, dut1)
        return erfa.c2t06a(tt[0].jd1, tt[0].jd2 + t / 86400.0, ut1a, ut1b, xp, yp)

    def rhs(t, y):
        M = rot(t)
        return np.r_[y[3:], M.T @ _pysh_accel(cilm, f, M @ y[:3], 20)]

    sol = solve_ivp(rhs, (0.0, t_out[-1]), x0, method="DOP853", t_eval=t_out, rtol=1e-13, atol=1e-7)
    assert sol.status == 0
    return sol.y.T


def test_one_day_in_leo_matches_an_independent_propagation_to_a_metre():
    """Earth world, truth_model = "egm2008_dop853", 1000 km / 45°, one day; the oracle starts from frame 0's state."""
    from renderlab.scenario import load_scenario
    from renderlab.worlds.earth import orientation
    from renderlab.worlds.earth.plan import EarthPlan

    sets = ["trajectory.start_s=0", "trajectory.frames=5", "trajectory.dt_s=21600"]
    sc, _ = load_scenario(REPO / "scenes" / "earth_leo.toml", [*sets, "trajectory.truth_model=egm2008_dop853"])
    plan = EarthPlan.from_scenario(sc)
    r = np.array([s["r_eci"] for s in plan.states])
    x0 = np.r_[plan.states[0]["r_eci"], plan.states[0]["v_eci"]]
    t = np.arange(5) * 21600.0
    eo = orientation.earth_orientation(plan.epoch, np.linspace(0.0, 86400.0, 25))
    ref = _oracle(x0, t, plan.epoch, eo)
    d = np.linalg.norm(r - ref[:, :3], axis=1)
    print(f"EGM2008 20x20, one day at 1000 km: lab vs independent {np.round(d, 3)} m")
    assert d.max() <= 1.0
    zonal, _ = load_scenario(REPO / "scenes" / "earth_leo.toml", [*sets, "trajectory.truth_model=zonal_dop853"])
    dz = np.linalg.norm(np.array([s["r_eci"] for s in EarthPlan.from_scenario(zonal).states]) - r, axis=1)
    print(f"tesseral and sectorial terms (20x20 vs J2-J6) after one day: {dz[-1] / 1e3:.2f} km")
    assert dz[-1] > 1e3


def test_onboard_j2_constants_and_the_truth_j2_differ_by_about_a_metre_a_day():
    """orbits.py (EGM96 J2, GM 3.986004418e14, R 6378137) against truth_orbit.py's EGM2008 J2 (GM 3.986004415e14,
    R 6378136.3), the same initial state, one day at 1000 km about +z: the figure both docstrings quote."""
    el = orbits.OrbitElements.circular(1000e3, 45.0)
    x0 = np.concatenate(el.state(0.0))
    t = np.array([0.0, 86400.0])
    onboard = propagate_truth(x0, t, TruthForces(field=ZonalField(orbits.MU_EARTH, orbits.R_EARTH,
                                                                  (orbits.J2_EARTH,)), degree=2, pole="+z"))
    truth = propagate_truth(x0, t, TruthForces(field=EGM2008, degree=2, pole="+z"))
    d = float(np.linalg.norm(onboard[-1, :3] - truth[-1, :3]))
    print(f"EGM96-J2/WGS-84 GM vs EGM2008 J2/GM after one day: {d:.2f} m")
    assert 0.2 < d < 5.0
