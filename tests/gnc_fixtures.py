"""A small descent world for the GN&C tests (test helper, not part of renderlab): the procedural EV5 shape at 32 m
facets (1280 faces), a landing site at (20°, 30°) in the frame the EV5 world builds (``site_frame``), a 20 m DEM of
analytic bumps at 25 cm cells in place of the rendered site, and the ARRM profile's waypoints over it."""

from __future__ import annotations

import functools
import math

import numpy as np
from tiny_ev5 import TINY_EV5_WORLD

OMEGA = 2 * math.pi / (3.725 * 3600)   # EV5 spin (Busch et al. 2011)
GM_TRUE, GM_ONBOARD, J2, R_REF = 2.9, 3.19, 0.05, 200.0


class BumpSite:
    """A site DEM with the attributes of renderlab.worlds.ev5.site.Site used by the truth and the waypoints."""

    def __init__(self, origin, R, half=10.0, cell=0.25):
        from renderlab.worlds.ev5 import terrain

        self.origin_m, self.R_body_from_site, self.cell_m, self.x0_m = origin, R, cell, -half
        t = -half + np.arange(int(round(2 * half / cell)) + 1) * cell
        X, Y = np.meshgrid(t, t)
        self.heights_m = 0.3 * np.sin(X / 3.0) * np.cos(Y / 4.0) - 0.002 * (X**2 + Y**2)
        self._interp = terrain.grid_interp

    def height_at(self, x, y):
        return self._interp(self.heights_m, self.x0_m, self.cell_m, x, y)


@functools.lru_cache(maxsize=1)
def world():
    """(shape, site, t0, x0, waypoints) of the descent from the 200 m waypoint to a target 0.7 m east, 0.4 m south
    of the site centre, touchdown at 5 cm/s."""
    from renderlab.studies.descent_gnc.waypoints import arrm_waypoints
    from renderlab.worlds.ev5 import stream
    from renderlab.worlds.ev5.config import EV5DescentTrajectory, EV5World
    from renderlab.worlds.ev5.descent import DescentProfile
    from renderlab.worlds.ev5.shape import procedural_shape
    from renderlab.worlds.ev5.site import site_frame

    shape = procedural_shape(EV5World(seed=5, facet_m=32.0), stream(5, "shape"))
    o, R = site_frame(shape, 20.0, 30.0, 30.0)
    site = BumpSite(o, R)
    t0, x0, wps = arrm_waypoints(DescentProfile(EV5DescentTrajectory()), OMEGA, site, target_xy=(0.7, -0.4),
                                 touchdown_speed_mps=0.05)
    return shape, site, t0, x0, wps


def truth(kind: str):
    """The truth dynamics over the test world with gravity ``kind`` (point_mass_j2 or polyhedron)."""
    from renderlab.dynamics.descent_truth import ContactSurface, DescentTruth, make_gravity

    shape, site, *_ = world()
    grav = make_gravity(kind, gm_m3_s2=GM_TRUE, j2=J2, r_ref_m=R_REF, vertices=shape.vertices, faces=shape.faces)
    return DescentTruth(grav, OMEGA, ContactSurface(shape.vertices, shape.faces, site))


def guidance(name: str = "zem_zev", period: float = 1.0, **kw):
    """A registered guidance law made for the test world's waypoints."""
    from renderlab import plugins
    from renderlab.contracts.guidance import GuidanceOptions

    wps = world()[4]
    return plugins.guidance.get(name)(GuidanceOptions(wps, GM_ONBOARD, (0.0, 0.0, OMEGA), period, **kw))


# The tiny EV5 descent_gnc scenario (64², 2 spp, two methods) shared by the study and gravity-mesh tests.
TINY_GNC_SCENARIO = 'name = "ev5_gnc_tiny"\n' + TINY_EV5_WORLD + """[trajectory]
kind = "ev5_descent"
sampling = "rate"
start_time_s = 900.0
frame_rate_hz = 0.0033333333333
frames = 4
[camera]
width = 64
height = 64
fx = 609.0
fy = 609.0
cx = 31.5
cy = 31.5
[render]
spp = 2
seed = 3
near_clip_m = 0.01
[campaign]
seed = 17
study = "descent_gnc"
[descent_gnc]
methods = ["spc", "ncc_baseline"]
control_period_s = 4.0
camera_period_s = 300.0
max_landmarks = 4
"""
