"""Contracts: what a measurement method, a navigation filter or a pose estimator receives and returns,
and the one table schema per kind of observable that runners, scorers, reports and tests all import.

- :mod:`.reasons`: the documented enum of *why there is no result* per kind (``reason`` column).
- :mod:`.landmark`: landmark-shift methods (Retina, SPC, your own): :class:`LandmarkMethod`,
  :class:`LandmarkFrame` in, :class:`LandmarkResult` out.
- :mod:`.navigation`: navigation filters (coastline EKF, descent filter): :class:`NavigationFilter`.
- :mod:`.pose`: pose / inertia estimators of an unknown satellite: :class:`PoseEstimator`.
- :mod:`.error_model`: landmark error models a geometric flight injects: :class:`LandmarkErrorModel`.
- :mod:`.study`: what a campaign runs (:class:`~renderlab.contracts.study.Study`).
- :mod:`.schemas`: the pyarrow schemas of the measurement, filter and pose tables (imports pyarrow; everything else
  here is numpy only). The onboard estimators (``estimators/``) do not import the contracts: they stay
  self-contained, and the lab's adapters (:mod:`renderlab.measurement`) translate their results.

Every table has an explicit ``has_result`` (bool) and a categorical ``reason`` (one value of the kind's enum,
``"ok"`` when there is a result). ``diagnostics`` is free text of the producer's own flags (for people, not for
scoring): no column's meaning depends on who wrote it.
"""
