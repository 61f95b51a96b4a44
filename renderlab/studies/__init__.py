"""One package per study: its scenario section (``config``), run function, study-specific scoring, figures,
demo piece and publish command. Each package's ``STUDY`` (:class:`renderlab.contracts.study.Study`) is
registered by name in :data:`renderlab.plugins.studies`; ``campaign/`` and ``report/`` stay generic.

- :mod:`.analytic_pointing`: centroid vs ellipse fit on the analytic proving scene.
- :mod:`.retina_vs_spc`: Retina, SPC-style and the baseline landmark methods on an EV5 descent (Wright et al. Fig. 12).
- :mod:`.coastline_ekf`: the coastline-matching EKF (Straub & Christian), geometric and image-in-the-loop,
  and the coastline visibility analysis (their Fig. 4).
- :mod:`.unknown_satellite`: monocular pose and inertia of an unknown tumbling satellite (Ivanov et al.).
"""
