"""Guidance, control and thrusters of the closed-loop descent (estimators.gnc behind renderlab.plugins.guidance):
the sampled-data ZEM/ZEV law against the exact double integrator and the continuous law, touchdown with perfect
navigation and thrusters in the truth dynamics (point mass + J2 and polyhedron), the thruster model's error
statistics, and landing dispersion under thruster errors, reproducible for a seed."""

from __future__ import annotations

import math

import gnc_fixtures as fx
import numpy as np
import pytest

from estimators.gnc import ThrusterModel, ThrusterOptions, Waypoint, ZemZevGuidance, ZemZevOptions
from renderlab.errors import UserError


def _double_integrator_flight(period: float, kick_at: int | None = None):
    """Fly a force-free double integrator (GM 0, no spin) to a waypoint 100 s ahead, each command held over 1 s
    (the closed-form step), optionally with a velocity kick before step ``kick_at``; returns (position miss,
    velocity miss, control energy ∫|a|² dt)."""
    target = Waypoint(100.0, (5.0, -3.0, 2.0), (0.0, 0.0, 0.01))
    law = ZemZevGuidance(ZemZevOptions((target,), 0.0, control_period_s=period))
    r, v, energy = np.ones(3), np.array([0.1, 0.0, -0.05]), 0.0
    for k in range(100):
        if k == kick_at:
            v = v + np.array([3e-3, -2e-3, 1e-3])
        a = law.command(float(k), np.r_[r, v])
        r, v, energy = r + v + 0.5 * a, v + a, energy + float(a @ a)
    return np.linalg.norm(r - target.r_m), np.linalg.norm(v - target.v_mps), energy


def test_sampled_law_is_the_minimum_energy_hold_sequence_and_tends_to_the_continuous_law():
    dr, dv, e4 = _double_integrator_flight(1.0)
    cr, cv, e3 = _double_integrator_flight(0.0)      # the continuous gains 6/t², 2/t held over 1 s
    assert max(dr, dv, cr, cv) < 1e-12               # both land an undisturbed double integrator
    assert e4 < e3                                   # G4 with less control energy
    # an error entering two periods before the end: G4 still lands exactly, G3 held over 1 s does not
    dr, dv, _ = _double_integrator_flight(1.0, kick_at=98)
    cr, cv, _ = _double_integrator_flight(0.0, kick_at=98)
    assert max(dr, dv) < 1e-12 and cr > 1e-3 and cv > 1e-3
    # as the hold shrinks, the first command is G3: a = 6 ZEM / t² − 2 ZEV / t (here ZEM, ZEV of a free particle)
    t_go, r, v = 80.0, np.array([1.0, 2.0, -1.0]), np.array([0.02, -0.01, 0.03])
    wp = Waypoint(t_go, (3.0, 0.0, 1.0), (0.0, 0.1, 0.0))
    zem, zev = np.array(wp.r_m) - (r + v * t_go), np.array(wp.v_mps) - v
    g3 = 6 * zem / t_go**2 - 2 * zev / t_go
    a = ZemZevGuidance(ZemZevOptions((wp,), 0.0, control_period_s=t_go / 4000)).command(0.0, np.r_[r, v])
    np.testing.assert_allclose(a, g3, rtol=2e-3)


@pytest.mark.parametrize("gravity", ["point_mass_j2", "polyhedron"])
def test_touchdown_with_perfect_navigation_and_thrusters(gravity):
    from renderlab.dynamics.closed_loop import fly

    shape, site, t0, x0, wps = fx.world()
    flight = fly(fx.truth(gravity), fx.guidance(), t0, x0, control_period_s=1.0, t_max_s=wps[-1].t_s + 60)
    assert flight.touchdown
    x = flight.x_touchdown
    assert np.linalg.norm(x[:3] - wps[-1].r_m) <= 0.01
    assert np.linalg.norm(x[3:] - wps[-1].v_mps) <= 1e-3
    assert abs(flight.t_s[-1] - wps[-1].t_s) < 1.0
    s = (x[:3] - site.origin_m) @ site.R_body_from_site      # contact is on the DEM
    assert abs(s[2] - float(site.height_at(s[0], s[1]))) < 1e-6
    k = int(np.flatnonzero(np.isclose(flight.t_s, wps[0].t_s))[0])   # through the spin-matched 50 m waypoint
    assert np.linalg.norm(flight.x_true[k, :3] - wps[0].r_m) < 0.01
    assert np.linalg.norm(flight.x_true[k, 3:]) < 1e-3
    assert np.abs(flight.a_cmd).max() < 0.01               # a gentle descent (m/s²)


def _thruster_flight(seed: int, sigma: float):
    """From the 50 m waypoint, point mass + J2 truth, thrusters with errors of scale ``sigma``."""
    from renderlab.dynamics.closed_loop import fly

    _, _, _, _, wps = fx.world()
    opts = ThrusterOptions(mass_kg=500.0, max_accel_mps2=0.05, min_impulse_bit_ns=0.05 * (sigma > 0),
                           scale_bias_sigma=2 * sigma, scale_sigma=sigma, misalignment_sigma_rad=sigma,
                           pointing_sigma_rad=sigma)
    thr = ThrusterModel(opts, np.random.default_rng(seed))
    x0 = np.r_[wps[0].r_m, 0.0, 0.0, 0.0]
    f = fly(fx.truth("point_mass_j2"), fx.guidance(), wps[0].t_s, x0, control_period_s=1.0,
            t_max_s=wps[-1].t_s + 60, thrusters=thr)
    assert f.touchdown
    return f, thr


def test_thruster_errors_grow_the_landing_dispersion_reproducibly():
    wps = fx.world()[4]

    def miss(sigma):
        """(position, velocity) touchdown misses of seeds 1–3, m and m/s; the flights."""
        flights = [_thruster_flight(s, sigma) for s in (1, 2, 3)]
        e = np.array([np.r_[f.x_touchdown[:3] - wps[-1].r_m, f.x_touchdown[3:] - wps[-1].v_mps] for f, _ in flights])
        return np.linalg.norm(e[:, :3], axis=1), np.linalg.norm(e[:, 3:], axis=1), flights

    p0, v0, perfect = miss(0.0)
    assert np.ptp(p0) == 0 and np.ptp(v0) == 0            # no thruster error: every seed lands the same
    p1, v1, _ = miss(0.005)
    p2, v2, flights = miss(0.05)
    rms = lambda a: float(np.sqrt(np.mean(a**2)))  # noqa: E731
    assert rms(p0) < rms(p1) < rms(p2) / 3 and rms(v0) < rms(v1) < rms(v2) / 3
    assert rms(p2) < 0.01 and rms(v2) < 1e-3               # the feedback keeps them small
    again, thr = _thruster_flight(2, 0.05)
    assert again.trajectory_bytes() == flights[1][0].trajectory_bytes()
    assert thr.delta_v_mps == flights[1][1].delta_v_mps > 0


def test_thruster_model_statistics_and_impulse_bit():
    # minimum impulse bit: below b/2 nothing, between b/2 and b one bit, above it the commanded impulse (T1)
    b, m, dt = 0.2, 100.0, 1.0
    thr = ThrusterModel(ThrusterOptions(mass_kg=m, min_impulse_bit_ns=b), np.random.default_rng(0))
    a = thr.realise(np.array([0.3, 0.7, -1.5]) * b / (m * dt), dt)
    np.testing.assert_allclose(a * m * dt, [0.0, b, -1.5 * b], atol=1e-15)
    assert thr.impulse_ns == pytest.approx(2.5 * b)
    # magnitude: mean 1 + s0, spread σ_s; pointing: the angle to the command has E[θ²] = 2 σ_p² (T2, T3)
    n, ss, sp = 4000, 0.01, 0.002
    thr = ThrusterModel(ThrusterOptions(mass_kg=m, scale_bias_sigma=0.03, scale_sigma=ss, pointing_sigma_rad=sp),
                        np.random.default_rng(7))
    cmd = np.array([0.01, -0.02, 0.005])
    out = np.array([thr.realise(cmd, dt) for _ in range(n)])
    ratio = np.linalg.norm(out, axis=1) / np.linalg.norm(cmd)
    assert abs(ratio.mean() - (1 + thr.scale0)) < 4 * ss / math.sqrt(n)
    assert ratio.std() == pytest.approx(ss, rel=0.05)
    ang = np.arccos(np.clip(out @ cmd / (np.linalg.norm(out, axis=1) * np.linalg.norm(cmd)), -1, 1))
    assert np.mean(ang**2) == pytest.approx(2 * sp**2, rel=0.08)
    # saturation per thruster axis
    sat = ThrusterModel(ThrusterOptions(mass_kg=m, max_accel_mps2=0.01), np.random.default_rng(0))
    np.testing.assert_allclose(sat.realise(np.array([0.05, -0.002, -0.3]), dt), [0.01, -0.002, -0.01])
    with pytest.raises(UserError, match="rotation"):
        ThrusterModel(ThrusterOptions(R_frame_from_thrusters=((1, 0, 0), (0, 1, 0), (0, 0, 2))),
                      np.random.default_rng(0))


def test_registry_protocol_and_a_users_own_law():
    from renderlab import plugins
    from renderlab.contracts.guidance import GuidanceLaw, GuidanceOptions
    from renderlab.dynamics.closed_loop import fly
    from renderlab.measurement.builtin_guidance import ZemZevLaw

    assert plugins.guidance.get("zem_zev") is ZemZevLaw
    assert isinstance(fx.guidance(), GuidanceLaw)
    with pytest.raises(UserError, match="unknown guidance law 'zem_zv'.*did you mean 'zem_zev'"):
        plugins.guidance.get("zem_zv")
    with pytest.raises(UserError, match="unknown parameter"):
        fx.guidance(params={"gain": 2.0})
    with pytest.raises(UserError, match="times must increase"):
        ZemZevGuidance(ZemZevOptions((Waypoint(2.0, (0, 0, 1), (0, 0, 0)), Waypoint(1.0, (0, 0, 1), (0, 0, 0))), 1.0))

    class HoverThenDrop:
        """A user's law: hold the last waypoint's velocity, cancelling the onboard free acceleration."""

        name = "drop"

        def __init__(self, options: GuidanceOptions):
            self.inner = ZemZevGuidance(ZemZevOptions(options.waypoints[-1:], options.gm_m3_s2, options.omega_rad_s))
            self.v = np.asarray(options.waypoints[-1].v_mps, float)

        def command(self, t_s, x_est):
            return -self.inner.free_acceleration(x_est[:3], x_est[3:]) + (self.v - x_est[3:]) / 5.0

    plugins.guidance.register("drop", HoverThenDrop)
    try:
        wps = fx.world()[4]
        law = plugins.guidance.get("drop")(GuidanceOptions(wps, fx.GM_ONBOARD, (0.0, 0.0, fx.OMEGA)))
        f = fly(fx.truth("point_mass_j2"), law, wps[-2].t_s, np.r_[wps[-2].r_m, wps[-2].v_mps], control_period_s=1.0,
                t_max_s=wps[-2].t_s + 300)
        assert f.touchdown and np.linalg.norm(f.x_touchdown[3:] - wps[-1].v_mps) < 1e-3
    finally:
        plugins.guidance.unregister("drop")
