"""Closed-loop GN&C descent: guidance and control fly on the navigation's estimate, the truth follows the thrust.

The building blocks of the closed-loop descent study: the ARRM profile as guidance waypoints (:mod:`.waypoints`),
the registered guidance law ``zem_zev`` behind the lab's contract (:mod:`.guidance`), and the loop
navigation → guidance → thrusters → truth dynamics until contact (:mod:`.loop`; truth:
:mod:`renderlab.dynamics.descent_truth`, gravity :mod:`renderlab.dynamics.polyhedron_gravity`; onboard guidance and
thrusters: :mod:`estimators.gnc`), and the same loop navigating on images rendered where the vehicle really is
(:func:`.render_loop.fly_closed_loop`: ``renderlab.Renderer``, a landmark method, the descent EKF) with the
open-loop replay beside it (:mod:`.replay`). Study ``descent_gnc`` (:data:`STUDY`): :mod:`.study` (one Monte Carlo
run), :mod:`.tables` (its rows), :mod:`.report` (the report section), options :mod:`.config`. The names below
are imported on first use (the study registry stays light).
"""

from importlib import import_module

from renderlab.contracts.study import Study, lazy

_LAZY = {"Flight": ".loop", "TruthPlusNoise": ".loop", "fly": ".loop", "ClosedLoopOptions": ".render_loop",
         "ClosedLoopRun": ".render_loop", "fly_closed_loop": ".render_loop", "arrm_waypoints": ".waypoints",
         "fly_replay": ".replay"}

STUDY = Study(name="descent_gnc", run=lazy("renderlab.studies.descent_gnc.study:run"), worlds=("ev5",),
              description="closed-loop GN&C descent to touchdown: each landmark method flies its own loop, "
                          "the open-loop replay beside it",
              check=lazy("renderlab.studies.descent_gnc.study:check"),
              report_sections=lazy("renderlab.studies.descent_gnc.report:report_sections"),
              own_tables=("gnc_images", "gnc_runs"), clusters=("run",))

__all__ = ["STUDY", *sorted(_LAZY)]


def __getattr__(name: str):
    if name in _LAZY:
        return getattr(import_module(_LAZY[name], __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
