"""The closed GN&C loop with images on the tiny EV5 world (64 × 64 px, 2 spp): every camera time renders the true
state through ``Renderer`` at the true time (``spec_at``; the record names the planned frame nearest in time), a
landmark method measures the image at the filter's a-priori pose, the descent EKF updates, the guidance flies on its estimate. Same seed: the same run byte
for byte (trajectory and images); another seed (another initial navigation error): another true path and other
images."""

from __future__ import annotations

import math

import numpy as np
import pytest
from tiny_ev5 import TINY_EV5_WORLD

SCENE = 'name = "gnc_render"\n' + TINY_EV5_WORLD + """
[trajectory]
kind = "ev5_descent"
sampling = "rate"
start_time_s = 1500.0
frame_rate_hz = 1.0
frames = 4
[camera]
width = 64
height = 64
fx = 300.0
fy = 300.0
cx = 31.5
cy = 31.5
[render]
spp = 2
near_clip_m = 0.01
"""


@pytest.fixture(scope="module")
def renderer(tmp_path_factory):
    from renderlab import Renderer

    path = tmp_path_factory.mktemp("gnc") / "scene.toml"
    path.write_text(SCENE)
    with Renderer(path) as r:
        yield r


METHOD = "spc"


def _run(renderer, seed: int):
    from renderlab import plugins
    from renderlab.contracts.guidance import GuidanceOptions
    from renderlab.dynamics.descent_truth import ContactSurface, DescentTruth, PointMassJ2
    from renderlab.studies.descent_gnc.config import DescentGncConfig
    from renderlab.studies.descent_gnc.render_loop import fly_closed_loop
    from renderlab.studies.descent_gnc.waypoints import arrm_waypoints
    from renderlab.worlds.ev5.descent import DescentProfile

    model = renderer.plan.model
    omega = 2 * math.pi / model.spin.period_s
    _, _, wps = arrm_waypoints(DescentProfile(renderer.scenario.trajectory), omega, model.site)
    truth = DescentTruth(PointMassJ2(2.9, 0.05, 200.0), omega,
                         ContactSurface(model.shape.vertices, model.shape.faces, model.site))
    law = plugins.guidance.get("zem_zev")(GuidanceOptions(wps, 3.19, (0.0, 0.0, omega), 1.0))
    t0 = wps[0].t_s                                            # from the spin-matched 50 m waypoint
    x0 = np.r_[wps[0].r_m, 0.0, 0.0, 0.0]
    cfg = DescentGncConfig(camera_period_s=1.0, initial_position_sigma_m=0.3, initial_velocity_sigma_mps=0.005,
                           gsd_ratio_range=(0.4, 2.5), sigma_ground_m=0.0, widen_factors=[1.0],
                           nis_reject_probability=1.0)
    return fly_closed_loop(renderer, METHOD, law, cfg, truth=truth, t0_s=t0, x0=x0, t_max_s=t0 + 3.0, seed=seed,
                           keep_images=True)


def test_closed_loop_renders_the_true_state_and_replays_for_a_seed(renderer):
    a = _run(renderer, 1)
    b = _run(renderer, 1)
    c = _run(renderer, 2)
    assert len(a.images) == 3 and len(a.dn) == 3                   # camera at t0, t0 + 1, t0 + 2
    # each image is rendered where the vehicle really is; its record names the planned frame nearest in time
    for rec in a.images:
        k = int(np.flatnonzero(np.isclose(a.flight.t_s, rec["t_s"]))[0])
        np.testing.assert_array_equal(rec["position_m"], a.flight.x_true[k, :3])
        assert rec["frame"] == int(round(rec["t_s"] - 1500.0))
    assert sum(r["n_results"] for r in a.images) > 0             # the method measured landmarks
    # the same seed: byte for byte; another seed: another initial error, another path, other images
    assert a.flight.trajectory_bytes() == b.flight.trajectory_bytes()
    assert all(x.tobytes() == y.tobytes() for x, y in zip(a.dn, b.dn))
    assert not np.allclose(a.x0_est, c.x0_est)
    assert np.abs(a.flight.x_true[1:, :3] - c.flight.x_true[1:, :3]).max() > 1e-6
    assert any(x.tobytes() != y.tobytes() for x, y in zip(a.dn[1:], c.dn[1:]))
