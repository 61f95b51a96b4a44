"""Study package of the error budget of the landmark methods against the registration Cramér–Rao bound: every error
source of the ``retina_vs_spc`` campaign switched on alone (:mod:`.plan`), run by the generic one-at-a-time core
(:mod:`renderlab.campaign.oat_budget`, :mod:`renderlab.campaign.oat_tables`), reported from its tables alone
(:mod:`.report`, :mod:`renderlab.stats.oat_budget`); the sources, the shadow term and the probes (their tables made by
``investigations/error_budget/``) are described in ``docs/retina_vs_spc.md``::

    python -m renderlab.studies.retina_vs_spc.budget run --out results/error_budget --runs 10 --workers 2
    python -m renderlab.studies.retina_vs_spc.budget report results/error_budget

The navigation budget (:mod:`.navigation`) joins this study to ``descent_navigation``, so it is a command above both:
``renderlab navigation-budget results/error_budget --runs 200`` (:mod:`renderlab.commands.navigation_budget`).
"""
