"""Study ``analytic_pointing``: the sphere's centre by a blob centroid and an ellipse fit on the analytic proving
scene, scored against its projected truth (a smoke test of the campaign engine); :mod:`.run`, :mod:`.report`."""

from renderlab.contracts.study import Study, lazy

STUDY = Study(name="analytic_pointing", run=lazy("renderlab.studies.analytic_pointing.run:run"), worlds=("analytic",),
              description="sphere centre by blob centroid vs ellipse fit on the analytic scene",
              report_sections=lazy("renderlab.studies.analytic_pointing.report:report_sections"),
              clusters=("run",))  # each run renders its own perturbed truth
