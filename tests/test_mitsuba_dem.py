"""The DEM design (renderlab.render.mitsuba_dem: the site traced by the pyramid march, nothing built per frame)
against the two-scene design with every tile at level 0 (the same triangles, in an Embree structure per frame).

A tiny EV5 descent (30 m site at 5 cm cells, 96², 4 spp) rendered twice with the same seeds; ``lod_pixels`` 0.01
puts every tile at level 0, so both designs hold the DEM's own triangles (the tiles' skirts hang below them)."""

from __future__ import annotations

import numpy as np
import pytest
from tiny_ev5 import render_with_tile_design, tiled_descent

SCENARIO = tiled_descent("dem_design", "lod = true\ntile_cells = 32\nlod_pixels = 0.01\n", [120.0, 30.0, 15.0])


def _render(tmp_path, design: str):
    backend, _, frames, plan = render_with_tile_design(tmp_path, SCENARIO, design)
    return backend, frames, plan.static_scene.tiled[0].site, plan


@pytest.fixture(scope="module")
def renders(tmp_path_factory):
    mp = pytest.MonkeyPatch()
    mp.setenv("RENDERLAB_CACHE", str(tmp_path_factory.mktemp("labcache")))
    tmp = tmp_path_factory.mktemp("dem_design")
    try:
        yield {d: _render(tmp, d) for d in ("dem", "two")}
    finally:
        mp.undo()


def test_dem_design_is_used(renders):
    from renderlab.render.mitsuba_dem import DemScene
    from renderlab.render.mitsuba_two_scene import TileScene

    assert isinstance(renders["dem"][0]._two, DemScene) and isinstance(renders["two"][0]._two, TileScene)


def test_truth_aovs_and_radiance_match_the_level_0_tiles(renders):
    """Same body and range at every site pixel centre; a different facet normal only where the centre ray meets an
    edge shared by two facets (either answer is exact there: a tie). Measured: ≤ 39 of 9216 pixels per frame, range
    within 3.2e-5 m everywhere, radiance differing on ≤ 0.09 % of pixels."""
    _, a, site, _ = renders["dem"]
    _, b, _, _ = renders["two"]
    for fa, fb in zip(a, b):
        on_site = fb.body_id == 1
        assert on_site.mean() > 0.5  # the site fills most of the frame
        same_id = fa.body_id == fb.body_id
        assert same_id.mean() >= 0.999, same_id.mean()
        both = on_site & same_id
        assert np.abs(fa.range_m - fb.range_m)[both].max() <= 1e-4
        assert np.abs(fa.position - fb.position)[both].max() <= 1e-4
        other_facet = both & (np.abs(fa.normal - fb.normal).max(-1) > 1e-5)
        assert other_facet.mean() <= 0.01
        uv = (site.to_site(fb.position[other_facet])[:, :2] - site.x0_m) / site.cell_m
        f = uv - np.floor(uv)
        to_edge = np.minimum.reduce([f[:, 0], f[:, 1], 1 - f[:, 0], 1 - f[:, 1], np.abs(f[:, 0] - f[:, 1])])
        assert np.all(to_edge < 1e-3), to_edge.max()
        differ = np.abs(fa.radiance - fb.radiance) > 1e-4 * fb.radiance.max()
        assert differ.mean() <= 0.005, differ.mean()


def test_the_static_scene_skipped_under_the_dem_changes_no_bit(renders):
    """Over the site's clear square (renderlab.render.dem_clearance) the static scene is not searched by camera rays
    and shadow rays are tested against it only from where they leave the square: every frame rendered again with the
    square emptied (the static scene tested on every ray) gives the same bytes. The square covers the site inside its
    border strip (1.5 global facets, where the global facets are only 2 cm under the DEM) up to the global facets
    that straddle the strip's edge (one more facet); the camera is over it in the two low frames."""
    from renderlab.render.dem_clearance import ClearSquare

    backend, frames, site, plan = renders["dem"]
    dem = backend._two
    sq = dem.squares[0]
    n = site.heights_m.shape[0]
    facet_cells = 4.0 / 0.05  # the tiny world's 4 m global facets in 5 cm cells
    assert (n - 1) / 2 - 2.5 * facet_cells <= sq.r < (n - 1) / 2 and sq.blocked_cells > 0
    clear = []
    for k, (spec, fa) in enumerate(zip(plan.frames, frames)):
        dem.squares = [sq]
        backend.render(spec, seed=11 + k)
        clear.append(dem.camera_clear[0])
        dem.squares = [ClearSquare(sq.u_c, sq.v_c, 0.0, sq.blocked_cells)]
        fb = backend.render(spec, seed=11 + k)
        assert not dem.camera_clear[0]
        for name in ("radiance", "position", "normal", "range_m", "body_id"):
            assert np.array_equal(getattr(fa, name), getattr(fb, name), equal_nan=True), (k, name)
    dem.squares = [sq]
    assert clear == [False, True, True]
