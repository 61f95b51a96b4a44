"""Closed-loop smoke example without images: ZEM/ZEV guidance flying the truth dynamics from the 200 m waypoint to
contact on a navigation that is the truth plus a seeded initial error and noise, through thrusters with seeded
errors. The same seed gives the same trajectory byte for byte; different initial errors give different true
trajectories (the vehicle flies on its estimate)."""

from __future__ import annotations

import gnc_fixtures as fx
import numpy as np

from estimators.gnc import ThrusterModel, ThrusterOptions
from renderlab.dynamics.closed_loop import TruthPlusNoise, fly


def _run(seed: int):
    """One seeded closed-loop run: the seed draws the initial navigation error, the noise and the thrusters."""
    _, _, t0, x0, wps = fx.world()
    nav_ss, thr_ss = np.random.SeedSequence(seed).spawn(2)
    rng = np.random.default_rng(nav_ss)
    e0 = np.r_[rng.normal(0, 1.0, 3), rng.normal(0, 0.01, 3)]          # 1 m, 1 cm/s initial error
    nav = TruthPlusNoise(0.01, 2e-4, rng, initial_error=e0, decay_s=120.0)
    thr = ThrusterModel(ThrusterOptions(mass_kg=500.0, max_accel_mps2=0.02, min_impulse_bit_ns=0.02,
                                        scale_sigma=0.01, pointing_sigma_rad=0.005), np.random.default_rng(thr_ss))
    flight = fly(fx.truth("point_mass_j2"), fx.guidance(max_accel_mps2=0.02), t0, x0, control_period_s=1.0,
                 t_max_s=wps[-1].t_s + 120.0, navigation=nav, thrusters=thr)
    return flight, e0


def test_closed_loop_smoke_is_reproducible_and_flies_on_its_estimate():
    wps = fx.world()[4]
    a, e_a = _run(7)
    b, _ = _run(7)
    c, e_c = _run(8)
    assert a.trajectory_bytes() == b.trajectory_bytes()
    assert not np.allclose(e_a, e_c)
    # different initial errors: the commands differ and so does the true path
    n = min(len(a.t_s), len(c.t_s))
    assert np.abs(a.x_true[:n, :3] - c.x_true[:n, :3]).max() > 0.1
    assert np.abs(a.a_cmd[0] - c.a_cmd[0]).max() > 0
    for f in (a, c):
        assert f.touchdown                                              # flown from 200 m to contact
        assert np.linalg.norm(f.x_touchdown[:3] - wps[-1].r_m) < 0.1     # near the target on a noisy estimate
        assert np.all(np.linalg.norm(f.a_cmd, axis=1) <= 0.02 + 1e-15)
