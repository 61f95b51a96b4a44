"""``render.shadows`` and the direct-sun integrator (``renderlab/render/mitsuba_direct.py``) on real renders.

* Shadows off, every registered backend (Mitsuba, and Cycles where bpy is installed), frame 0 of
  ``scenes/analytic_sphere_box.toml`` with centre sampling: the ground pixels in the cast shadows of the sphere
  and the box (found by an independent numpy ray caster, ``tests/oracles.py``) equal the closed-form unshadowed
  radiance A·E·cos(i)/π to 1e-3; with shadows on (the default) the same pixels are black; the sphere's attached
  shadow (cos i < 0) stays black either way.
* Shadows on: ``rl_direct_sun`` (two rays per sample) renders the image of Mitsuba's ``path`` integrator with
  ``max_depth = 2`` (three rays) from the same rays. For a delta (directional) sun no random number enters the
  radiance of a given ray (the emitter sample is exact, the continuation ray of ``path`` cannot reach the sun),
  so the two images differ by float32 rounding only: bound 1e-5 of the image maximum, box filter, 16 spp,
  Lambert, Lommel–Seeliger, McEwen and Hapke surfaces.
* The truth cache keys on the setting: a shadow-free render never reuses a shadowed cache entry.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import REPO, scenario_dict
from oracles import camera_rays, hit_box, hit_plane_z0, hit_sphere
from renderer_params import RENDERERS
from scipy import ndimage
from scipy.spatial.transform import Rotation

SCENE = REPO / "scenes" / "analytic_sphere_box.toml"


def _render(sets, renderer="mitsuba", integrator="auto", seed=3):
    from renderlab.pipeline import frame_specs, make_backend
    from renderlab.render.mitsuba_backend import MitsubaBackend
    from renderlab.scenario import load_scenario
    from renderlab.worlds.analytic import build_scene

    sc, base = load_scenario(SCENE, sets)
    old, MitsubaBackend.integrator = MitsubaBackend.integrator, integrator
    try:
        backend = make_backend(sc, build_scene(sc.world, base), renderer)
    finally:
        MitsubaBackend.integrator = old
    spec = frame_specs(sc)[0]
    try:
        return backend.render(spec, seed=seed), spec, sc, backend
    finally:
        if hasattr(backend, "close"):
            backend.close()


def _oracle(spec, sc, shape):
    """Centre-ray closed form of the scene: (unshadowed Lambert radiance, cast-shadow mask, id, cos i) per pixel;
    id 0 ground, 1 sphere, 2 box, −1 miss (the box's Lommel–Seeliger radiance is not needed here)."""
    ground, sphere, box = sc.world.bodies
    H, W = shape
    ll, ss = np.mgrid[0:H, 0:W]
    o, d = camera_rays(spec, np.column_stack([ss.ravel(), ll.ravel()]).astype(float))
    R_box = Rotation.from_euler("xyz", box.rotation_deg, degrees=True).as_matrix()
    c_s, c_b, half = np.array(sphere.center_m), np.array(box.center_m), np.array(box.size_m) / 2

    def t_box(o, d):  # slab test in the box frame
        return hit_box((o - c_b) @ R_box, d @ R_box, -half, half)

    ts = np.stack([hit_plane_z0(o, d, np.array(ground.size_m) / 2), hit_sphere(o, d, c_s, sphere.radius_m), t_box(o, d)])
    t, ids = ts.min(axis=0), np.argmin(ts, axis=0)
    ids = np.where(np.isfinite(t), ids, -1)
    p = o + np.where(np.isfinite(t), t, 0.0)[:, None] * d
    n = np.where((ids == 1)[:, None], (p - c_s) / sphere.radius_m, [0.0, 0.0, 1.0])
    sun = np.asarray(spec.sun.direction_render, float)
    sun = sun / np.linalg.norm(sun)
    E = spec.sun.irradiance_w_m2
    cos_i = n @ sun
    albedo = np.where(ids == 1, sphere.albedo, ground.albedo)
    unshadowed = albedo * E * np.clip(cos_i, 0, None) / np.pi
    q, s = p + 1e-6 * n, np.broadcast_to(sun, p.shape)
    cast = (ids == 0) & (np.isfinite(hit_sphere(q, s, c_s, sphere.radius_m)) | np.isfinite(t_box(q, s)))
    return [a.reshape(shape) for a in (unshadowed, cast, ids, cos_i)]


def _interior(mask, ids):
    """Pixels of ``mask`` whose 3×3 neighbourhood is all in ``mask`` and has one id (no edge pixels)."""
    one = ndimage.minimum_filter(ids, 3) == ndimage.maximum_filter(ids, 3)
    return one & (ndimage.minimum_filter(mask.astype(np.uint8), 3) > 0)


@pytest.mark.parametrize("renderer", RENDERERS)
def test_shadows_off_gives_the_closed_form_unshadowed_radiance(renderer):
    centre = ["render.pixel_filter=center", "render.spp=1"]
    off, spec, sc, _ = _render(centre + ["render.shadows=false"], renderer)
    on, _, _, _ = _render(centre, renderer)
    expect, cast, ids, cos_i = _oracle(spec, sc, off.radiance.shape)
    shadowed = _interior(cast & (cos_i > 0.05), ids)
    lit = _interior((ids <= 1) & (ids >= 0) & ~cast & (cos_i > 0.05), ids)
    attached = _interior((ids == 1) & (cos_i < -0.05), ids)
    print(f"{renderer}: {shadowed.sum()} cast-shadow, {lit.sum()} lit, {attached.sum()} attached-shadow pixels")
    assert shadowed.sum() > 300 and lit.sum() > 1000 and attached.sum() > 50
    rel_off = np.abs(off.radiance[shadowed] / expect[shadowed] - 1)
    rel_lit = np.abs(off.radiance[lit] / expect[lit] - 1)
    print(f"{renderer}: shadows off, max relative error {rel_off.max():.2e} in cast shadows, {rel_lit.max():.2e} lit")
    assert rel_off.max() <= 1e-3 and rel_lit.max() <= 1e-3
    assert np.abs(on.radiance[lit] / expect[lit] - 1).max() <= 1e-3
    assert np.all(on.radiance[shadowed] <= 1e-6 * expect.max())  # the switch is what lights them
    assert np.all(off.radiance[attached] == 0) and np.all(on.radiance[attached] == 0)


@pytest.mark.parametrize("laws", [("lambert", "lommel_seeliger"), ("hapke", "mcewen")])
def test_direct_sun_integrator_renders_the_path_depth_2_image(laws):
    sets = [f"world.bodies.1.law=\"{laws[0]}\"", f"world.bodies.2.law=\"{laws[1]}\""]
    direct, _, _, be_d = _render(sets)  # the default ("auto") at max_depth 2
    path, _, _, be_p = _render(sets, integrator="path")
    assert type(be_d.scene.integrator()).__name__ == "DirectSun"
    assert "PathIntegrator" in str(be_p.scene.integrator())
    a, b = direct.radiance.astype(np.float64), path.radiance.astype(np.float64)
    diff = np.abs(a - b) / b.max()
    lit = b > 0.01 * b.max()
    print(f"{laws}: max |direct - path| / max = {diff.max():.1e}; lit-pixel means {a[lit].mean():.4f} vs "
          f"{b[lit].mean():.4f} over {lit.sum()} px")
    assert lit.sum() > 10000
    assert diff.max() <= 1e-5
    np.testing.assert_array_equal(direct.body_id, path.body_id)


def test_shadows_false_needs_direct_sunlight():
    from renderlab.errors import UserError
    from renderlab.render.mitsuba_direct import integrator_dict
    from renderlab.scenario import load_scenario

    with pytest.raises(UserError, match="shadows = false needs max_depth = 2"):
        load_scenario(SCENE, ["render.shadows=false", "render.max_depth=3"])
    with pytest.raises(UserError, match="needs the direct-sun integrator"):
        integrator_dict(2, False, "path")
    assert integrator_dict(3, True)["type"] == "path"
    assert integrator_dict(2, True)["type"] == "rl_direct_sun" and integrator_dict(2, True, "path")["type"] == "path"


def test_truth_cache_never_reuses_a_shadowed_render_for_shadow_free_truth(tmp_path):
    from renderlab.campaign.cache import cached_truthset
    from renderlab.files.truthset import TruthSet
    from renderlab.scenario import scenario_from_dict

    paths = {}
    for shadows in (True, False, True):
        sc = scenario_from_dict(scenario_dict(render={"spp": 1, "pixel_filter": "center", "seed": 1,
                                                      "near_clip_m": 0.01, "far_clip_m": 1000.0, "shadows": shadows}))
        path, hit = cached_truthset(sc, REPO / "scenes", tmp_path, frames=1)
        assert hit == (shadows in paths), f"shadows={shadows}: hit={hit}"
        paths[shadows] = path
    assert paths[True] != paths[False]
    L = {k: TruthSet.open(p).load(0).radiance for k, p in paths.items()}
    brighter = L[False] > L[True] + 1.0
    assert brighter.sum() > 20 and np.all(L[False] >= L[True] - 1e-3)  # the sphere's shadow lit, nothing darker


def test_scalar_fallback_direct_sun_matches_path_and_switches_shadows_off():
    """The scalar variant (the fallback without LLVM) runs the same integrator ray by ray (misses included)."""
    from renderlab.pipeline import frame_specs, make_backend
    from renderlab.render.mitsuba_backend import MitsubaBackend
    from renderlab.scenario import scenario_from_dict
    from renderlab.worlds.analytic import build_scene

    out = {}
    for integrator, shadows in (("auto", True), ("path", True), ("auto", False)):
        sc = scenario_from_dict(scenario_dict(render={"variant": "scalar_rgb", "spp": 1, "pixel_filter": "center",
                                                      "shadows": shadows, "near_clip_m": 0.01, "far_clip_m": 1000.0}))
        MitsubaBackend.integrator = integrator
        try:
            backend = make_backend(sc, build_scene(sc.world, REPO / "scenes"), "mitsuba")
        finally:
            MitsubaBackend.integrator = "auto"
        assert backend.scalar
        out[integrator, shadows] = backend.render(frame_specs(sc)[0], seed=1).radiance
    direct, path, off = out["auto", True], out["path", True], out["auto", False]
    assert (direct == 0).sum() > 50  # misses and the sphere's shadow are in view
    np.testing.assert_allclose(direct, path, rtol=0, atol=1e-5 * path.max())
    lit_by_switch = off > direct + 1.0
    assert lit_by_switch.sum() > 20 and np.all(off >= direct - 1e-3)


def test_truth_cache_keeps_renders_of_another_ray_path_or_integrator_apart(tmp_path, monkeypatch):
    """A truth set rendered with ``ray_path = "drjit_grid"`` (``$RENDERLAB_MITSUBA_RAYS``) or ``integrator =
    "path"`` is its own cache entry: never served for the default path, and the default's entry is still a hit."""
    from renderlab.campaign.cache import cached_truthset
    from renderlab.files.truthset import TruthSet
    from renderlab.render.mitsuba_backend import MitsubaBackend
    from renderlab.scenario import scenario_from_dict

    sc = scenario_from_dict(scenario_dict(render={"spp": 2, "pixel_filter": "box", "seed": 1,
                                                  "near_clip_m": 0.01, "far_clip_m": 1000.0}))
    default, hit = cached_truthset(sc, REPO / "scenes", tmp_path, frames=1)
    assert not hit
    monkeypatch.setattr(MitsubaBackend, "ray_path", "drjit_grid")
    grid, hit = cached_truthset(sc, REPO / "scenes", tmp_path, frames=1)
    assert not hit and grid != default
    monkeypatch.setattr(MitsubaBackend, "ray_path", "drjit")
    monkeypatch.setattr(MitsubaBackend, "integrator", "path")
    path, hit = cached_truthset(sc, REPO / "scenes", tmp_path, frames=1)
    assert not hit and path not in (default, grid)
    monkeypatch.setattr(MitsubaBackend, "integrator", "auto")
    again, hit = cached_truthset(sc, REPO / "scenes", tmp_path, frames=1)
    assert hit and again == default
    assert [len(TruthSet.open(p)) for p in (default, grid, path)] == [1, 1, 1]
