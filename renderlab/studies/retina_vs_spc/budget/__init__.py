"""Study package of the error budget of the landmark methods against the registration Cramér–Rao bound (what each
error source adds), over the generic one-at-a-time core (:mod:`renderlab.campaign.oat_budget`,
:mod:`renderlab.campaign.oat_tables`, :mod:`renderlab.stats.oat_budget`, :mod:`renderlab.report.budget_figure`).

Every error source of the ``retina_vs_spc`` campaign is switched on alone, all others off, on the published
reduced EV5 scenario (``results/retina_vs_spc/scenario.toml``), plus "all off" and "all on"; every
method of :data:`METHODS` (Retina with the paper's 3×3 peak step, ``retina_refined`` with the ``gaussian_2d``
step, ``retina_ml`` with the maximum-likelihood shift of :mod:`estimators.retina.ml_shift`, SPC, the NCC baseline)
measures the same frames. The switches are scenario keys, nothing else:

==================== ============================================================================
source               "on" = the base scenario's value of
==================== ============================================================================
sensor_noise         ``retina_vs_spc.sensor_noise`` (off: the noise-free expected DN, rounded)
mapping_error        ``world.mapping_error_m`` (maplet height error; off: 0)
albedo_error         ``world.albedo_error_rms`` (maplet albedo error; off: 0)
photometric_law      ``world.law`` / ``law_params`` (Hapke truth; off: McEwen truth, the onboard form,
                     so the onboard L(α) fit is exact)
apriori_pose         ``perturbations.apriori_position_sigma_m``, ``apriori_attitude_sigma_deg``
camera_knowledge     ``perturbations.focal_length_sigma_frac``, ``principal_point_sigma_px``,
                     ``distortion_sigma``
sun_knowledge        ``perturbations.sun_direction_sigma_deg``
maplet_spacing       ``perturbations.maplet_spacing_sigma_frac``
==================== ============================================================================

The peak step is not a scenario switch but a method: ``retina`` (3×3 step) beside ``retina_refined`` in every
configuration (:mod:`renderlab.stats.oat_budget` reports the difference). The shadow approximation is measured the same way,
at all off: configuration ``no_shadows`` is every source off with no cast shadows in the truth
(``render.shadows = false``) nor in the methods' predictions (:mod:`.shadows` says why both); every
other configuration has ray-traced cast shadows in the truth and each method's own shadowing in its template.
``run --only CONFIG ...`` runs just those configurations into an existing folder's tables (the rest kept);
``run --methods METHOD ...`` just those methods of every configuration (same seeds and run indices, so their rows
are paired with the others'; the merge checks the truth columns and knowledge draws agree).

The truth render depends only on the world keys (law, mapping and albedo error: five truth sets, the
others share the "all off" one through the truth cache). Configurations with no random draw (sensor
noise off, no perturbation on) give identical runs, so they run once. Every configuration uses the same
campaign seed and run indices, so runs ``i`` of two configurations share their noise and draws (common
random numbers). Written, into ``--out``: ``tables/budget_measurements.parquet`` (every row of every run,
column ``config``), ``tables/budget_configs.parquet`` (configuration, source, runs, overrides as JSON),
``tables/budget_perturbations.parquet``, ``budget.json`` (command, seed, runs) and the report
(:mod:`.report`), which ``report`` makes again from the tables alone::

    python -m renderlab.studies.retina_vs_spc.budget run --out results/error_budget --runs 10 --workers 2
    python -m renderlab.studies.retina_vs_spc.budget probe results/error_budget   # template sampling (.probe)
    python -m renderlab.studies.retina_vs_spc.budget report results/error_budget

The navigation budget (each configuration's landmark errors flown through the descent filter,
:mod:`.navigation`) joins this study to ``descent_navigation``, so it is a command above both:
``renderlab navigation-budget results/error_budget --runs 200`` (:mod:`renderlab.commands.navigation_budget`).
"""

