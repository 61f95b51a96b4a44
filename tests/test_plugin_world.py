"""A world added by registration only (no lab file edited): a plug-in 'moon' world with its own [world] model, the
lab's camera-path trajectories, and a make_plan; a scenario with ``world.kind = "moon"`` validates and renders
(Mitsuba), its sphere's rendered Lambert radiance against A·E·cos(i)/π."""

from __future__ import annotations

from typing import Literal

import numpy as np
import pytest
from pydantic import Field

from renderlab.contracts.config_types import Positive, Strict


class MoonWorld(Strict):
    kind: Literal["moon"] = "moon"
    radius_m: Positive = Field(1737.4, description="Mean radius [m] (scaled down for the test)")
    albedo: float = Field(0.12, ge=0, le=1, description="Lambert albedo [1]")


def moon_plan(scenario, base_dir):
    from scipy.spatial.transform import Rotation

    from renderlab.photometry import make_law
    from renderlab.render.scene import BodySpec, SceneDescription
    from renderlab.worlds.base import WorldPlan, frame_specs

    w = scenario.world
    body = BodySpec(name="moon", body_id=0, shape="sphere", center_m=np.zeros(3),
                    R_render_from_body=Rotation.identity().as_matrix(), law=make_law("lambert"), albedo=w.albedo,
                    radius_m=w.radius_m)
    return WorldPlan(frames=frame_specs(scenario, base_dir), render_frame={"name": "MOON_FIXED"},
                     static_scene=SceneDescription(bodies=[body], render_frame={"name": "MOON_FIXED"}))


@pytest.fixture()
def moon():
    from renderlab import plugins
    from renderlab.contracts.world import WorldKind

    plugins.worlds.register("moon", WorldKind("moon", MoonWorld,
                                              {"orbit": "renderlab.scenario.trajectory:TrajectoryConfig"}, moon_plan))
    yield
    plugins.worlds.unregister("moon")


SCENE = {"name": "moon_test", "world": {"kind": "moon", "radius_m": 2.0, "albedo": 0.12},
         "sun": {"direction": [1.0, 0.0, 0.3]},
         "camera": {"width": 48, "height": 32, "fx": 40.0, "fy": 40.0, "cx": 23.5, "cy": 15.5},
         "trajectory": {"kind": "orbit", "frames": 1, "range_m": 8.0, "elevation_deg": 10.0, "azimuth_start_deg": 0.0,
                        "azimuth_end_deg": 0.0},
         "render": {"spp": 4, "pixel_filter": "center"}}


def test_plugin_world_validates_and_renders(moon, tmp_path):
    from renderlab.files.truthset import TruthSet
    from renderlab.pipeline import render_truthset
    from renderlab.scenario import scenario_from_dict

    sc = scenario_from_dict(SCENE, "moon scenario")
    assert sc.world.kind == "moon" and isinstance(sc.world, MoonWorld)
    out = render_truthset(sc, tmp_path, tmp_path / "moon", progress=False)
    fr = TruthSet.open(out).load(0)
    hit = fr.id == 0
    assert hit.sum() > 100
    sun = np.array(SCENE["sun"]["direction"]) / np.linalg.norm(SCENE["sun"]["direction"])
    n = fr.normal[hit].astype(float)
    cos_i = n @ sun
    lit = cos_i > 0.2
    expect = 0.12 * 1361.0 * cos_i[lit] / np.pi
    np.testing.assert_allclose(fr.radiance[hit][lit], expect, rtol=1e-3)


def test_unregistered_world_kind_is_one_line(tmp_path):
    from renderlab.errors import UserError
    from renderlab.scenario import scenario_from_dict

    with pytest.raises(UserError, match="world"):
        scenario_from_dict(SCENE, "moon scenario")
