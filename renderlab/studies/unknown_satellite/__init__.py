"""Study ``unknown_satellite``: monocular pose and inertia of an unknown tumbling satellite (Ivanov et al.):
:mod:`.sequence` (one rendered sequence through stage 1 and stage 2), :mod:`.run` (one campaign run),
:mod:`.figures`, :mod:`.report_section`, :mod:`.observability` (Fisher information vs arc length; its report blocks in
:mod:`.report_section`), :mod:`.demo`."""

from renderlab.contracts.study import Study, lazy

STUDY = Study(name="unknown_satellite", run=lazy("renderlab.studies.unknown_satellite.run:run"), worlds=("microsat",),
              description="pose and inertia of an unknown tumbling microsatellite (Ivanov et al.)",
              report_sections=lazy("renderlab.studies.unknown_satellite.report_section:study_section"),
              own_tables=("stage2", "inertia_observability"),
              publish_tables=lazy("renderlab.studies.unknown_satellite.figures:publish_tables"),
              demo=lazy("renderlab.studies.unknown_satellite.demo:run_demo_unknown_satellite"))
