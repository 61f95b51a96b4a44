"""Study ``descent_gnc``: each landmark method flies its own closed GN&C loop down to contact, the open-loop replay
beside it on the same draws.

One run (:func:`run`): the run's seed gives two children, the navigation draws and the thruster draws, and **every
method's flight uses the same two** (paired). Per method the closed loop
(:func:`~renderlab.studies.descent_gnc.render_loop.fly_closed_loop`), then the replay
(:func:`~renderlab.studies.descent_gnc.replay.fly_replay`). The nominal flight (perfect navigation, ideal thrusters)
is flown once per process: the control error is the true position minus the nominal one at the same time. Tables:
:mod:`.tables`; report: :mod:`.report`; ``docs/descent_gnc.md``.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from renderlab import plugins
from renderlab.campaign.run_truth import truth_perturbations_on
from renderlab.dynamics.closed_loop import fly
from renderlab.errors import UserError
from renderlab.studies.descent_gnc.config import DescentGncConfig

_NOMINAL: dict = {}


def section(scenario) -> DescentGncConfig:
    """The scenario's ``[descent_gnc]`` section (defaults when absent)."""
    return getattr(scenario, "descent_gnc", None) or DescentGncConfig()


def check(scenario) -> None:
    """Refuse what the study cannot run, before any output: world, trajectory, truth perturbations, names."""
    if scenario.world.kind != "ev5" or scenario.trajectory.kind != "ev5_descent":
        raise UserError(f"study descent_gnc needs world.kind 'ev5' with an 'ev5_descent' trajectory, got "
                        f"'{scenario.world.kind}'")
    on = truth_perturbations_on(scenario.perturbations)
    if on:
        raise UserError(f"study descent_gnc flies its own true trajectories; perturbations.{on[0]} is not supported "
                        "(the study disperses the initial estimate, the sensors and the thrusters)")
    cfg = section(scenario)
    for name in cfg.methods:
        plugins.landmark_methods.get(name, where="descent_gnc.methods: ")
    plugins.guidance.get(cfg.guidance, where="descent_gnc.guidance: ")


class Setup:
    """What every flight of a world shares: the renderer, truth dynamics, waypoints, start state, guidance maker."""

    def __init__(self, renderer, cfg: DescentGncConfig):
        from renderlab.dynamics.descent_truth import ContactSurface, DescentTruth, make_gravity
        from renderlab.studies.descent_gnc.waypoints import arrm_waypoints
        from renderlab.worlds.ev5.descent import DescentProfile

        model = renderer.plan.model
        self.renderer, self.cfg, self.site = renderer, cfg, model.site
        self.omega = 2.0 * math.pi / model.spin.period_s
        self.t0, self.x0, self.waypoints = arrm_waypoints(
            DescentProfile(renderer.scenario.trajectory), self.omega, model.site, target_xy=cfg.target_xy_m,
            touchdown_speed_mps=cfg.touchdown_speed_mps)
        body = None
        if cfg.gravity == "polyhedron":   # the rendered mesh is cut under the site: the closed uncut body instead
            from renderlab.worlds.ev5.gravity_mesh import gravity_mesh

            body = gravity_mesh(renderer.scenario.world, renderer.base_dir, cfg.gravity_facet_m)
        gravity = make_gravity(cfg.gravity, gm_m3_s2=cfg.gm_true_m3_s2, j2=cfg.j2_true, r_ref_m=cfg.r_ref_m,
                               vertices=None if body is None else body.vertices,
                               faces=None if body is None else body.faces)
        self.truth = DescentTruth(gravity, self.omega, ContactSurface(model.shape.vertices, model.shape.faces,
                                                                      model.site))
        self.t_max = self.waypoints[-1].t_s + cfg.t_max_after_target_s

    def guidance(self):
        from renderlab.contracts.guidance import GuidanceOptions

        return plugins.guidance.get(self.cfg.guidance)(GuidanceOptions(
            self.waypoints, self.cfg.gm_filter_m3_s2, (0.0, 0.0, self.omega), self.cfg.control_period_s,
            self.cfg.max_accel_mps2))

    def thrusters(self, seed: int | None):
        """A fresh thruster set drawing from ``seed`` (None: ideal, no errors)."""
        from estimators.gnc import ThrusterModel, ThrusterOptions

        c = self.cfg
        opts = ThrusterOptions(mass_kg=c.mass_kg, isp_s=c.isp_s) if seed is None else ThrusterOptions(
            mass_kg=c.mass_kg, max_accel_mps2=c.max_accel_mps2, min_impulse_bit_ns=c.min_impulse_bit_ns,
            scale_bias_sigma=c.scale_bias_sigma, scale_sigma=c.scale_sigma,
            misalignment_sigma_rad=math.radians(c.misalignment_sigma_deg),
            pointing_sigma_rad=math.radians(c.pointing_sigma_deg), isp_s=c.isp_s)
        return ThrusterModel(opts, np.random.default_rng(0 if seed is None else seed))

    def nominal(self, key: str):
        """The nominal flight (perfect navigation, ideal thrusters), flown once per process and world."""
        if key not in _NOMINAL:
            _NOMINAL.clear()
            _NOMINAL[key] = fly(self.truth, self.guidance(), self.t0, self.x0,
                                control_period_s=self.cfg.control_period_s, t_max_s=self.t_max,
                                thrusters=self.thrusters(None))
        return _NOMINAL[key]


def run(scenario, base_dir, run_index: int, seed_sequence, workdir) -> dict:
    """One run of ``descent_gnc`` → ``{"gnc_images": table, "gnc_runs": table}`` (module docstring)."""
    from renderlab.campaign.cache import loaded_world, truth_key
    from renderlab.scenario import scenario_from_dict, truth_dict
    from renderlab.studies.descent_gnc.render_loop import fly_closed_loop
    from renderlab.studies.descent_gnc.replay import fly_replay
    from renderlab.studies.descent_gnc.tables import Recorder

    check(scenario)
    cfg = section(scenario)
    truth_sc = scenario_from_dict(truth_dict(scenario.to_dict()), "descent_gnc truth scenario")
    renderer = loaded_world(truth_sc, Path(base_dir))
    setup = Setup(renderer, cfg)
    nominal = setup.nominal(truth_key(truth_sc.to_dict()) + cfg.model_dump_json())
    ss_nav, ss_thr = seed_sequence.spawn(2)
    nav_seed, thr_seed = int(ss_nav.generate_state(1)[0]), int(ss_thr.generate_state(1)[0])
    rec = Recorder(scenario.name, int(run_index), setup, nominal, cfg)
    for method in cfg.methods:
        thr = setup.thrusters(thr_seed)
        t_start = time.perf_counter()
        flown = fly_closed_loop(renderer, method, setup.guidance(), cfg, truth=setup.truth, t0_s=setup.t0,
                                x0=setup.x0, t_max_s=setup.t_max, seed=nav_seed, thrusters=thr)
        rec.add(method, "closed", flown, thr, time.perf_counter() - t_start)
    if cfg.replay:
        thr = setup.thrusters(thr_seed)
        t_start = time.perf_counter()
        flown = fly_replay(renderer, list(cfg.methods), setup.guidance(), cfg, truth=setup.truth, t0_s=setup.t0,
                           x0=setup.x0, t_max_s=setup.t_max, seed=nav_seed, thrusters=thr)
        wall = (time.perf_counter() - t_start) / len(cfg.methods)
        for method in cfg.methods:
            rec.add(method, "replay", flown[method], thr, wall)
    return rec.tables()
