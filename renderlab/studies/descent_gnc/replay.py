"""The open-loop replay beside the closed loops: the guidance flies on the truth (the open-loop design of
``results/descent_navigation``), each camera time is rendered **once**, and every method's own
:class:`~renderlab.studies.descent_gnc.render_loop.ImageNavigation` (its filter and draws from the same seed as its
closed loop: paired) measures that image; an image's render time is shared equally among the methods' records."""

from __future__ import annotations

import numpy as np

from renderlab.dynamics.closed_loop import fly
from renderlab.studies.descent_gnc.render_loop import ClosedLoopRun, ImageNavigation


class ReplayNavigation:
    """Perfect navigation for the guidance; the methods' filters ride along on the images (module docstring)."""

    def __init__(self, navs: list):
        self.navs = navs

    def after_step(self, t0: float, t1: float, a_delivered) -> None:
        for nav in self.navs:
            nav.after_step(t0, t1, a_delivered)

    def estimate(self, t_s: float, x_true) -> np.ndarray:
        x_true = np.asarray(x_true, float)
        if self.navs[0].is_camera_time(t_s):
            atts = [nav.attitude(x_true) for nav in self.navs]          # each its own star-tracker draw (paired)
            dn, spec, t_render = self.navs[0].render(float(t_s), x_true, atts[0][0])
            for nav, (_, R_star) in zip(self.navs, atts):
                nav.measure_update(float(t_s), x_true, dn, spec, R_star, t_render / len(self.navs))
        return x_true.copy()


def fly_replay(renderer, methods, guidance, cfg, *, truth, t0_s: float, x0, t_max_s: float, seed: int,
               thrusters=None, look_at_m=None) -> dict:
    """``{method: ClosedLoopRun}`` of the replay (module docstring); every run holds the same flight."""
    target = renderer.plan.model.site.origin_m if look_at_m is None else look_at_m
    navs = [ImageNavigation(renderer, m, cfg, t0_s, x0, seed, target) for m in methods]
    flight = fly(truth, guidance, t0_s, x0, control_period_s=cfg.control_period_s, t_max_s=t_max_s,
                 navigation=ReplayNavigation(navs), thrusters=thrusters)
    return {m: ClosedLoopRun(flight, nav.images, nav.dn, nav.x0_est, nav.filt.x, nav.filt.P, nav.loss)
            for m, nav in zip(methods, navs)}
