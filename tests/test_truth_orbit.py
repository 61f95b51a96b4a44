"""The truth propagator (DOP853, zonal J2–J6, drag, SRP, Sun/Moon) against closed forms and the onboard-class model.

Oracles: Kepler's analytic solution (:meth:`OrbitElements.state`) in the two-body limit; Vallado's secular J2
nodal rate (eq. 9-41); the fixed-step RK4 two-body + J2 of :mod:`renderlab.dynamics.orbits` with the same
constants when the extra terms are off; conservation of energy and of the angular momentum about the pole in
the zonal-only case (a time-independent, axisymmetric potential); rotation covariance for a tilted pole;
closed-form magnitudes for drag, SRP and the lunar tide.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from renderlab.dynamics import orbits
from renderlab.dynamics.truth_orbit import (
    EGM2008,
    TruthForces,
    ZonalField,
    density_exponential,
    propagate_for,
    propagate_truth,
    zonal_accel,
    zonal_potential,
)

ONBOARD_J2 = ZonalField(orbits.MU_EARTH, orbits.R_EARTH, (orbits.J2_EARTH,), "onboard J2")
TT_2024 = (2460482.5, 0.41743)          # 2024-06-21 ~10:00 TT


@pytest.mark.parametrize("e", [0.0, 0.05, 0.2])
def test_two_body_limit_matches_kepler_to_a_millimetre(e):
    el = orbits.OrbitElements(7.0e6 / (1 - e), e, np.radians(63), np.radians(40), np.radians(100), np.radians(10))
    t = np.linspace(0, el.period_s, 31)
    r, v = el.state(t)
    x = propagate_truth(np.r_[r[0], v[0]], t, TruthForces(field=ONBOARD_J2, degree=0))
    err = np.linalg.norm(x[:, :3] - r, axis=1).max()
    print(f"e = {e}: DOP853 two-body vs Kepler over one orbit: {err * 1e3:.3f} mm")
    assert err < 1e-3 and np.abs(x[:, 3:] - v).max() < 1e-6


def test_j2_secular_raan_drift_matches_the_analytic_rate():
    el = orbits.OrbitElements.circular(1000e3, 45.0)
    t = np.arange(11) * el.period_s                                  # whole orbits: short-period terms repeat
    r0, v0 = el.state(0.0)
    x = propagate_truth(np.r_[r0, v0], t, TruthForces(field=ONBOARD_J2, degree=2, pole="+z"))
    rate = np.polyfit(t, np.unwrap(orbits.raan_of(x[:, :3], x[:, 3:])), 1)[0]
    expect = orbits.j2_nodal_rate(el)
    print(f"J2 nodal rate {np.degrees(rate) * 86400:.4f} deg/day, analytic {np.degrees(expect) * 86400:.4f}, "
          f"ratio - 1 = {rate / expect - 1:.1e}")
    assert abs(rate / expect - 1) < 5e-3                              # osculating vs mean a: O(J2)


def test_dop853_matches_rk4_j2_when_the_extra_terms_are_off():
    el = orbits.OrbitElements(7.1e6, 0.01, np.radians(97.5), np.radians(10), np.radians(30), 0.0)
    t = np.linspace(0, el.period_s, 13)
    x0 = np.concatenate(el.state(0.0))
    ref = orbits.propagate(x0, t, j2=True, max_step_s=1.0)
    x = propagate_truth(x0, t, TruthForces(field=ONBOARD_J2, degree=2, pole="+z"))
    d = np.linalg.norm(x[:, :3] - ref[:, :3], axis=1).max()
    print(f"DOP853 vs RK4 (1 s) two-body + J2 over one orbit: {d * 1e3:.3f} mm")
    assert d < 1e-3
    same = propagate_for(type("Cfg", (), {"truth_j2": True})(), x0, t, rk4_step_s=1.0)
    assert np.array_equal(same, ref)


def test_zonal_only_conserves_energy_and_polar_angular_momentum_tilted_pole():
    pole = np.array([0.004, -0.003, 1.0])                             # a GCRF-like pole, 0.3 deg off z
    el = orbits.OrbitElements(6.9e6, 0.02, np.radians(51.6), 0.3, 1.0, 0.0)
    t = np.linspace(0, 5 * el.period_s, 21)
    x = propagate_truth(np.concatenate(el.state(0.0)), t, TruthForces(degree=6, pole=pole))
    E = 0.5 * np.sum(x[:, 3:] ** 2, -1) - zonal_potential(x[:, :3], EGM2008, 6, pole)
    hz = np.cross(x[:, :3], x[:, 3:]) @ (pole / np.linalg.norm(pole))
    print(f"five orbits, J2-J6: |dE/E| {np.abs(E / E[0] - 1).max():.1e}, |dh_pole/h| {np.abs(hz / hz[0] - 1).max():.1e}")
    assert np.abs(E / E[0] - 1).max() < 1e-10 and np.abs(hz / hz[0] - 1).max() < 1e-10
    # rotation covariance: the same orbit about +z, rotated by the pole's rotation, is the same trajectory
    Q = Rotation.align_vectors([pole / np.linalg.norm(pole)], [[0, 0, 1.0]])[0].as_matrix()
    xz = propagate_truth(np.r_[Q.T @ x[0, :3], Q.T @ x[0, 3:]], t, TruthForces(degree=6, pole="+z"))
    assert np.linalg.norm(xz[:, :3] @ Q.T - x[:, :3], axis=1).max() < 1e-3


def test_zonal_acceleration_is_the_gradient_of_the_potential():
    rng = np.random.default_rng(4)
    r = rng.normal(0, 1, (20, 3))
    r = r / np.linalg.norm(r, axis=1, keepdims=True) * rng.uniform(6.5e6, 8e6, (20, 1))
    pole = np.array([0.1, 0.2, 1.0])
    a = zonal_accel(r, EGM2008, 6, pole)
    h = 1.0
    g = np.stack([(zonal_potential(r + h * e, EGM2008, 6, pole) - zonal_potential(r - h * e, EGM2008, 6, pole))
                  / (2 * h) for e in np.eye(3)], -1)
    assert np.abs(a - g).max() < 1e-8                                # m/s² (|a| ≈ 8)
    assert EGM2008.j[0] == pytest.approx(1.0826261738522e-3, rel=1e-12)   # J2 = −√5 C̄20
    assert EGM2008.j[1] == pytest.approx(-2.5324105185677e-6, rel=1e-10)


def test_drag_srp_and_third_body_have_their_closed_form_sizes():
    assert density_exponential(400e3) == pytest.approx(3.725e-12) and density_exponential(1000e3) == pytest.approx(
        3.019e-15)
    assert density_exponential(449.999e3) == pytest.approx(density_exponential(450e3), rel=1e-4)   # continuous
    el = orbits.OrbitElements.circular(400e3, 51.6)
    x0 = np.concatenate(el.state(0.0))
    t = np.array([0.0, el.period_s])
    base = propagate_truth(x0, t, TruthForces(degree=2, epoch_tt_jd=TT_2024, pole="+z"))
    for kw, lo, hi in ((dict(drag=True), 10.0, 2e3), (dict(srp=True), 0.05, 20.0),
                       (dict(third_body=True), 0.5, 200.0)):
        x = propagate_truth(x0, t, TruthForces(degree=2, epoch_tt_jd=TT_2024, pole="+z", **kw))
        d = np.linalg.norm(x[-1, :3] - base[-1, :3])
        print(f"{kw}: one orbit at 400 km moves the truth by {d:.2f} m")
        assert lo < d < hi, (kw, d)
    # drag takes energy out: the orbit decays
    x = propagate_truth(x0, t, TruthForces(degree=0, drag=True, pole="+z"))
    assert np.linalg.norm(x[-1, :3]) < np.linalg.norm(base[0, :3]) + 1.0
    with pytest.raises(ValueError, match="epoch_tt_jd"):
        propagate_truth(x0, t, TruthForces(third_body=True))


def test_earth_world_and_geometric_study_use_the_truth_propagator(repo):
    """``truth_model = "zonal_dop853"`` in a scenario's orbit, and in the geometric study's options, runs the
    truth propagator; the result departs from the two-body (onboard-class) model by kilometres in an hour."""
    from dataclasses import replace

    from renderlab.errors import UserError
    from renderlab.scenario import load_scenario
    from renderlab.studies.coastline_ekf.geometric import paper_orbit, truth_geometry
    from renderlab.worlds.earth.plan import EarthPlan

    base = ["trajectory.frames=3", "trajectory.dt_s=1200"]
    sc, _ = load_scenario(repo / "scenes/earth_leo.toml", base)
    kepler = EarthPlan.from_scenario(sc)
    sc2, _ = load_scenario(repo / "scenes/earth_leo.toml", base + ["trajectory.truth_model=zonal_dop853"])
    truth = EarthPlan.from_scenario(sc2)
    d = [np.linalg.norm(a["r_eci"] - b["r_eci"]) for a, b in zip(kepler.states, truth.states)]
    print(f"Earth world, zonal_dop853 vs Kepler: {np.round(d)} m")
    assert 1e3 < d[-1] < 1e5
    with pytest.raises(UserError, match="truth_model"):
        load_scenario(repo / "scenes/earth_leo.toml", base + ["trajectory.drag=true"])

    o = paper_orbit("i45_h1000", duration_s=3600.0)
    geo = truth_geometry(replace(o, truth_model="zonal_dop853", zonal_degree=6))
    geo_2b = truth_geometry(o)
    assert np.array_equal(geo.t_s, geo_2b.t_s)
    d = np.linalg.norm(geo.x_true[-1, :3] - geo_2b.x_true[-1, :3])
    print(f"geometric study, zonal_dop853 vs two-body RK4 after 1 h: {d:.0f} m")
    assert 1e3 < d < 1e5 and truth_geometry(replace(o, truth_j2=False)) is geo_2b
