"""One package per study: its scenario section (``config``), run function, study-specific scoring, figures and report
section. Each package's ``STUDY`` (:class:`renderlab.contracts.study.Study`) is registered by name in
:data:`renderlab.plugins.studies` (the list: docs/architecture.md); ``campaign/`` and ``report/`` stay generic, and
studies never import each other (import-linter)."""
