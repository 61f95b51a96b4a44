"""Blender Cycles backend: what only Cycles has. Its camera convention, Lambert closed form, OSL laws vs the
numpy references, Hapke at nadir, hard shadow edges and determinism are checked for every renderer backend in
``tests/test_backend_conformance.py`` (where its pinhole-only camera raises a one-line UserError)."""

from __future__ import annotations

import pytest
from conftest import REPO, scenario_dict

from renderlab.errors import UserError

pytest.importorskip("bpy")


def test_indirect_light_is_a_user_error():
    """Cycles renders direct sunlight only: max_depth ≠ 2 is refused when the backend is made."""
    from renderlab.pipeline import make_backend
    from renderlab.scenario import scenario_from_dict
    from renderlab.worlds.analytic import build_scene

    sc = scenario_from_dict(scenario_dict(render={"max_depth": 3}))
    with pytest.raises(UserError, match="direct sunlight only") as ei:
        make_backend(sc, build_scene(sc.world, REPO / "scenes"), "cycles")
    assert "\n" not in str(ei.value)
