"""Studies: truth-side drivers that run an estimator over many seeded runs and return result tables."""
