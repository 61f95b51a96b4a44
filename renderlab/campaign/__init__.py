"""Monte Carlo campaigns: plans, perturbations, executors (in-process, Dask), a resumable result store,
a truth-render cache, a study registry and scoring. Heavy imports (mitsuba, dask) stay inside functions."""
