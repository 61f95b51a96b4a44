"""Study ``planet_opnav``: centre finding and limb navigation of a resolved body (the ``planet`` world) over a grid of
ranges × phase angles × photometric laws, the lab's centre/limb methods and Basilisk's OpNav modules on the same
seeded images (:mod:`.run`, section :mod:`.config`). Scored and reported by the ``centre_limb`` kind
(:data:`renderlab.contracts.centre_limb.CENTRE_LIMB`: :mod:`renderlab.stats.centre_limb`,
:mod:`renderlab.report.centre_limb_section`); rows of one grid cell are correlated (the cluster)."""

from renderlab.contracts.study import Study, lazy

STUDY = Study(name="planet_opnav", run=lazy("renderlab.studies.planet_opnav.run:run"), worlds=("planet",),
              description="centre/limb OpNav of a resolved body: lab methods and Basilisk's modules on one grid",
              check=lazy("renderlab.studies.planet_opnav.run:check"), clusters=("cell",))
