"""Closed-loop GN&C descent: guidance and control fly on the navigation's estimate, the truth follows the thrust.

The building blocks of the closed-loop descent study: the ARRM profile as guidance waypoints (:mod:`.waypoints`),
the registered guidance law ``zem_zev`` behind the lab's contract (:mod:`.guidance`), and the loop
navigation → guidance → thrusters → truth dynamics until contact (:mod:`.loop`; truth:
:mod:`renderlab.dynamics.descent_truth`, gravity :mod:`renderlab.dynamics.polyhedron_gravity`; onboard guidance and
thrusters: :mod:`estimators.gnc`), and the same loop navigating on images rendered where the vehicle really is
(:func:`.render_loop.fly_closed_loop`: ``renderlab.Renderer``, a landmark method, the descent EKF).
"""

from renderlab.studies.descent_gnc.loop import Flight, TruthPlusNoise, fly
from renderlab.studies.descent_gnc.render_loop import ClosedLoopOptions, ClosedLoopRun, fly_closed_loop
from renderlab.studies.descent_gnc.waypoints import arrm_waypoints

__all__ = ["ClosedLoopOptions", "ClosedLoopRun", "Flight", "TruthPlusNoise", "arrm_waypoints", "fly",
           "fly_closed_loop"]
