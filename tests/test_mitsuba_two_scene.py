"""The two-scene design (renderlab.render.mitsuba_two_scene) against the one-scene design it replaces.

A tiny EV5 descent whose tile set changes every frame is rendered twice with the same seeds: the frame's tiles in
a second ``mi.Scene`` (the default) and merged into the one scene (``MitsubaBackend.tile_design = "merged"``).
The truth AOVs must be identical and the radiance identical but for a few shadow-edge samples; the static scene
must never be reloaded after the first frame (its structure is built once)."""

from __future__ import annotations

import numpy as np
import pytest
from tiny_ev5 import render_with_tile_design, tiled_descent

SCENARIO = tiled_descent("two_scene", "lod = true\ntile_cells = 32\n", [120.0, 60.0, 30.0, 15.0])


def _render(tmp_path, design: str):
    backend, static, frames, _ = render_with_tile_design(tmp_path, SCENARIO, design)
    return backend, static, frames


@pytest.fixture(scope="module")
def renders(tmp_path_factory, monkeypatch_module):
    tmp = tmp_path_factory.mktemp("two_scene")
    return {d: _render(tmp, d) for d in ("two", "merged")}


@pytest.fixture(scope="module")
def monkeypatch_module(tmp_path_factory):
    mp = pytest.MonkeyPatch()
    mp.setenv("RENDERLAB_CACHE", str(tmp_path_factory.mktemp("labcache")))
    yield mp
    mp.undo()


def test_two_scene_design_is_used_and_static_scene_is_built_once(renders):
    two, static, _ = renders["two"]
    one, _, _ = renders["merged"]
    assert two._two is not None and one._two is None
    assert two.scene is static  # never reloaded: the tile updates went to the second scene
    assert two._two.updates >= 3 and one._tiles.updates == two._two.updates  # the tile set changed every frame


def test_truth_aovs_identical_and_radiance_equal_but_for_shadow_edge_samples(renders):
    _, _, a = renders["two"]
    _, _, b = renders["merged"]
    for fa, fb in zip(a, b):
        assert (fa.body_id == 1).mean() > 0.5  # the site fills most of the frame
        np.testing.assert_array_equal(fa.body_id, fb.body_id)
        np.testing.assert_array_equal(fa.position, fb.position)
        np.testing.assert_array_equal(fa.normal, fb.normal)
        np.testing.assert_array_equal(fa.range_m, fb.range_m)
        differ = fa.radiance != fb.radiance
        # a differing pixel is a shadow-ray end point moved by float32 rounding (the sun's bounding sphere
        # is the static scene's here, the merged scene's there): at most one of the 4 samples flips
        # (measured on these frames: 0 pixels differ)
        assert differ.mean() <= 0.002, differ.mean()
        if differ.any():
            step = np.abs(fa.radiance - fb.radiance)[differ]
            assert np.all(step <= fb.radiance.max() / 4 * 1.001)


def test_default_design_on_llvm_is_two_scenes_and_a_bad_design_is_one_line(tmp_path, monkeypatch_module):
    from renderlab.errors import UserError

    backend, _, _ = _render(tmp_path, "auto")
    assert backend._two is not None  # llvm_ad_mono + direct sun
    with pytest.raises(UserError, match="tile design"):
        _render(tmp_path, "bvh")
