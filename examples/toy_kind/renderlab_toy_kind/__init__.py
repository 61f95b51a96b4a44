"""A toy observable kind, ``bright_spot`` (locate one bright spot in an image), added to renderlab by registration
alone: the package's entry points register the kind (``renderlab.observables``), two methods
(``renderlab.bright_spot_methods``) and a study (``renderlab.studies``); nothing under ``renderlab/`` names it.

Modules: :mod:`.kind` (reasons, frame, result, protocol, result schema, the :data:`~.kind.BRIGHT_SPOT` object),
:mod:`.methods` (``peak_pixel``, ``window_centroid``), :mod:`.parts` (runner, scorer, report section, conformance
harness), :mod:`.study` (synthetic frames with an exact truth).
"""
