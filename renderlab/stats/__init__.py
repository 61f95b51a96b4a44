"""Statistics for reports: intervals that respect the correlation structure of the data (:mod:`.bootstrap`)."""
