"""Study ``coastline_ekf``: coastline-matching navigation in LEO (Straub & Christian), geometric Monte Carlo
(:mod:`.geometric`) or image in the loop (:mod:`.image`), its report sections (:mod:`.report_section`,
:mod:`.figures`, :mod:`.scoring`), publish commands (:mod:`.publish`, :mod:`.publish_image`), the onboard
database (:mod:`.database`) and the coastline visibility analysis of their Fig. 4 (:mod:`.visibility`)."""

from renderlab.contracts.study import Study, lazy

STUDY = Study(name="coastline_ekf", run=lazy("renderlab.studies.coastline_ekf.study:run"), worlds=("earth",),
              description="coastline-matching EKF in LEO (Straub & Christian), geometric or image in the loop",
              report_sections=lazy("renderlab.studies.coastline_ekf.study:report_sections"),
              own_tables=("coastline_filter",), check=lazy("renderlab.worlds.earth:check_installed"),
              demo=lazy("renderlab.studies.coastline_ekf.study:run_demo_coastline"))
