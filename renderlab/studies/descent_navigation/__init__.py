"""Study ``descent_navigation``: landmark methods (Retina, SPC-style, the NCC baseline, any registered one) each
driving the onboard descent EKF (:mod:`estimators.descent_nav`) closed-loop down the ARRM descent over EV5
(Wright et al., Fig. 2). :mod:`.run` (one Monte Carlo run), :mod:`.loop` (one method's closed loop), :mod:`.truth`
(the true trajectory, gravity and control), :mod:`.sources` (what measures an image: a landmark method,
or a registered source such as ``geometric``, the true pixel + injected error), :mod:`.report` (the report section)."""

from renderlab.contracts.study import Study, lazy

STUDY = Study(name="descent_navigation", run=lazy("renderlab.studies.descent_navigation.run:run"), worlds=("ev5",),
              description="closed-loop descent navigation: landmark methods driving one EKF down the ARRM descent",
              check=lazy("renderlab.studies.descent_navigation.run:check"),
              report_sections=lazy("renderlab.studies.descent_navigation.report:report_sections"),
              own_tables=("descent_filter", "descent_landmarks", "descent_images", "descent_landmark_runs",
                          "descent_landmark_tiers", "descent_landmark_fit"), clusters=("run",),
              publish_tables=lazy("renderlab.studies.descent_navigation.publish:publish_tables"))
