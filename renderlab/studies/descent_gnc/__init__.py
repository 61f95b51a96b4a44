"""Closed-loop GN&C descent: guidance and control fly on the navigation's estimate, the truth follows the thrust.

Study ``descent_gnc`` (:data:`STUDY`): ARRM waypoints (:mod:`.waypoints`), the loop with images rendered where the
vehicle really is (:mod:`.render_loop`; the loop itself :mod:`renderlab.dynamics.closed_loop`) and the open-loop
replay (:mod:`.replay`); one run :mod:`.study`, rows :mod:`.tables`, report :mod:`.report`, options :mod:`.config`.
"""

from renderlab.contracts.study import Study, lazy

STUDY = Study(name="descent_gnc", run=lazy("renderlab.studies.descent_gnc.study:run"), worlds=("ev5",),
              description="closed-loop GN&C descent to touchdown: each landmark method flies its own loop, "
                          "the open-loop replay beside it",
              check=lazy("renderlab.studies.descent_gnc.study:check"),
              report_sections=lazy("renderlab.studies.descent_gnc.report:report_sections"),
              publish_tables=lazy("renderlab.studies.descent_gnc.scoring:publish_tables"),
              own_tables=("gnc_images", "gnc_runs"), clusters=("run",))
