"""Onboard-style estimators under test (numpy/scipy/numba/opencv only)."""
