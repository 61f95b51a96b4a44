"""Study ``retina_vs_spc``: landmark methods (Retina, SPC-style, and any registered one) on the same EV5 frames
(Wright et al., Fig. 12). :mod:`.run` (one Monte Carlo run), :mod:`.demo` (the demo's small campaign)."""

from renderlab.contracts.study import Study, lazy

STUDY = Study(name="retina_vs_spc", run=lazy("renderlab.studies.retina_vs_spc.run:run"), worlds=("ev5",),
              description="Retina vs SPC-style landmark measurement on an EV5 descent (Wright et al. Fig. 12)",
              demo=lazy("renderlab.studies.retina_vs_spc.demo:run_demo_campaign"),
              check=lazy("renderlab.studies.retina_vs_spc.run:check"),
              subsets=lazy("renderlab.studies.retina_vs_spc.report:subsets"),
              gross_error_px=lazy("renderlab.studies.retina_vs_spc.report:gross_error_px"),
              publish_tables=lazy("renderlab.studies.retina_vs_spc.report:publish_tables"))
