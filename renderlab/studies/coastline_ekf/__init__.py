"""Study ``coastline_ekf``: coastline-matching navigation in LEO (Straub & Christian), geometric Monte Carlo
(:mod:`.geometric`) or image in the loop (:mod:`.image`); report (:mod:`.report_section`), publish commands and
layouts (:mod:`.publish`, :mod:`.publish_image`). docs/coastline_ekf.md."""

from renderlab.contracts.study import Study, lazy

#: tables the study reports itself (the generic filter section skips them): the campaign's filter table, the modes
#: of a published image folder and the per-run rows of a published geometric one (:mod:`.publish`)
OWN_TABLES = ("coastline_filter", "geometric_filter", "variant_no_map_error_filter", "variant_map_error_in_filter_filter",
              "coastline_sample_runs", "coastline_runs")

STUDY = Study(name="coastline_ekf", run=lazy("renderlab.studies.coastline_ekf.study:run"), worlds=("earth",),
              description="coastline-matching EKF in LEO (Straub & Christian), geometric or image in the loop",
              report_sections=lazy("renderlab.studies.coastline_ekf.study:report_sections"),
              own_tables=OWN_TABLES, publish_tables=lazy("renderlab.studies.coastline_ekf.publish:publish_tables"),
              check=lazy("renderlab.worlds.earth:check_installed"),
              demo=lazy("renderlab.studies.coastline_ekf.study:run_demo_coastline"))
