"""Fixtures shared by the Earth tests (import them into a test module: ``from earth_fixtures import gshhg``).

GSHHG is parsed once per process (``load_gshhg`` caches it); the fixture makes that dependency explicit and
session-scoped, so whichever Earth test runs first pays the load and every other one reuses it.
"""

from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def gshhg():
    from renderlab.worlds.earth.gshhg import load_gshhg

    return load_gshhg()


def earth_scenario(repo, *overrides: str):
    """``scenes/earth_leo.toml`` with ``--set``-style overrides → (scenario, base_dir)."""
    from renderlab.scenario import load_scenario

    return load_scenario(repo / "scenes/earth_leo.toml", list(overrides))
