"""The Earth world's cloud layer: cover fraction, occlusion of the ground, determinism.

Oracles: (1) the global cover fraction of the field, sampled at uniformly random points on the globe, against
the configured fraction; (2) in a Mitsuba render, the pixels whose body id is the cloud layer against an
independent per-pixel prediction: the pixel-centre ray (CameraModel.unproject + true attitude) meets the
cloud shell (WGS-84 raised by the cloud altitude; ``ray_ellipsoid`` is checked against root finding in
test_earth_geometry) and the field is evaluated there. The mesh only samples the field once per cloud-grid
cell (≈ 1.5 km here against ≈ 8.5 km pixels), so pixels may disagree only where a cloud edge passes within
about a cell of the pixel centre (measured: 0.4 % of pixels); (3) cloud radiance against Lambert's law with
the normal AOV and the sun; (4) cloud shadows: ground pixels whose every point's ray towards the sun
crosses a cloudy part of the shell are dark, those whose rays all miss the clouds are lit. The frame is
taken with the sun 9° high so that shadows fall ≈ 2 pixels from their clouds: the epoch moves to
19:00 UTC and the RAAN by the Earth's rotation in 9 h (15.041°/h), which keeps the default ground track (Portugal).
"""

from __future__ import annotations

import earth_fixtures
import numpy as np
import pytest
from earth_fixtures import earth_scenario

from renderlab.pipeline import make_backend
from renderlab.worlds.earth import wgs84
from renderlab.worlds.earth.clouds import CloudField
from renderlab.worlds.earth.plan import CLOUD_ID, GROUND_ID

COVER = 0.67  # about two thirds of Earth is cloudy
# world.seed 1 gives the default frame (Portugal) both cloud (≈ 39 % of pixels) and ground; with seed 0 the
# same frame lies under one large cloud system (≈ 99 %) and could not show whether the ground is occluded

gshhg = earth_fixtures.gshhg  # session fixture: GSHHG parsed once for all Earth tests


@pytest.fixture(scope="module")
def cloudy_frame(repo, gshhg):
    from renderlab.worlds.earth import make_plan

    sc, base = earth_scenario(repo, "camera.width=64", "camera.height=64", "trajectory.frames=1",
                              "render.spp=1", f"world.cloud_cover={COVER}", "world.seed=1",
                              "trajectory.epoch_utc=2024-06-21T19:00:00Z", "trajectory.raan_deg=135.37")
    plan = make_plan(sc, base)
    spec = plan.frames[0]
    scene = plan.scene(plan.scene_key(spec))
    out = make_backend(sc, scene, "mitsuba").render(spec, seed=5)
    return plan, spec, scene, out


def test_global_cover_fraction_matches_setting():
    rng = np.random.default_rng(7)
    v = rng.normal(size=(20000, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)  # uniform on the sphere
    p = wgs84.geodetic_to_ecef(np.arcsin(v[:, 2]), np.arctan2(v[:, 1], v[:, 0]), 3000.0)
    for cover in (0.3, COVER):
        for seed in (0, 1):
            frac = CloudField(cover, seed).cloudy(p).mean()
            # one field realisation differs from the set fraction by σ ≈ 0.011 (measured over 12 seeds at 50k
            # points, both 0.3 and 0.67; 20k points add 0.0033 of sampling noise): allow 4σ
            assert abs(frac - cover) < 0.045, (cover, seed, frac)
    assert not CloudField(0.0).cloudy(p).any() and CloudField(1.0).cloudy(p).all()


def test_rendered_cloud_ids_match_field_along_pixel_rays(cloudy_frame):
    plan, spec, scene, out = cloudy_frame
    st, w = plan.states[0], plan.world
    ids = out.body_id
    assert set(np.unique(ids)) <= {GROUND_ID, CLOUD_ID}, "every pixel sees ground or cloud"
    d = spec.camera.unproject(spec.camera.pixel_grid().reshape(-1, 2)) @ st["R_ecef_from_cam"].T
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    t = wgs84.ray_ellipsoid(st["r_ecef"][None], d, w.cloud_altitude_m)
    expect = CloudField(w.cloud_cover, w.seed, scale_min_m=w.cloud_scale_m).cloudy(st["r_ecef"] + t[:, None] * d)
    got = ids.ravel() == CLOUD_ID
    frac_got, frac_expect, mismatch = got.mean(), expect.mean(), np.mean(got != expect)
    print(f"cloud pixels {frac_got:.3f}, field along rays {frac_expect:.3f}, mismatched pixels {mismatch:.3f}")
    assert 0.1 < frac_expect < 0.95, "the test frame must show both cloud and ground"
    assert abs(frac_got - frac_expect) < 0.02
    assert mismatch < 0.04  # cloud edges within a cloud-grid cell of a pixel centre
    # cloud hits lie on the cloud shell, ground hits on the ellipsoid: the ground is occluded, not mixed in
    rf = scene.render_frame
    P = out.position.reshape(-1, 3).astype(np.float64)
    _, _, h = wgs84.ecef_to_geodetic(P @ np.asarray(rf["R_ecef_from_render"]).T + np.asarray(rf["origin_ecef_m"]))
    assert np.all(np.abs(h[got] - w.cloud_altitude_m) < 10.0) and np.all(np.abs(h[~got]) < 10.0)
    # direct sunlight only (max_depth 2): a cloud pixel away from cloud edges (3×3 ids alike, so every
    # sub-pixel sample hits cloud) shows Lambert radiance albedo·E·cos(i)/π, cos(i) from the normal AOV
    same = np.ones_like(ids, bool)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            same &= np.roll(np.roll(ids, dy, 0), dx, 1) == ids
    same[[0, -1], :] = same[:, [0, -1]] = False
    cos_i = out.normal.reshape(-1, 3).astype(np.float64) @ spec.sun.direction_render
    lam = w.cloud_albedo * spec.sun.irradiance_w_m2 * cos_i / np.pi
    inner_cloud = same.ravel() & got
    assert inner_cloud.sum() > 100
    rel = np.abs(out.radiance.ravel()[inner_cloud] / lam[inner_cloud] - 1).max()
    print(f"cloud radiance vs Lambert: max relative error {rel:.2e} over {inner_cloud.sum()} pixels")
    # the radiance sample lies up to 0.7 px (≈ 7 km) from the pixel centre whose normal gives cos(i): the
    # normal turns by ≈ 1.1e-3 rad there, and with the sun 9° high that changes cos(i) by ≈ 0.7 % (max 0.9 %
    # measured)
    assert rel < 0.015
    # clouds cast shadows: a ground point is dark where its ray to the sun crosses a cloudy part of the shell.
    # The render samples one random point per pixel (spp 1), so judge only pixels that the oracle finds wholly
    # shadowed or wholly lit: at the centre and the four corners (±½ px) of the pixel
    field = CloudField(w.cloud_cover, w.seed, scale_min_m=w.cloud_scale_m)
    s = np.asarray(st["sun_ecef"], float)
    s = s / np.linalg.norm(s)
    grid = spec.camera.pixel_grid().reshape(-1, 2)
    votes = []
    for off in ((0, 0), (-0.5, -0.5), (0.5, -0.5), (-0.5, 0.5), (0.5, 0.5)):
        d = spec.camera.unproject(grid + off) @ st["R_ecef_from_cam"].T
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        g = st["r_ecef"] + wgs84.ray_ellipsoid(st["r_ecef"][None], d)[:, None] * d
        lat, lon, _ = wgs84.ecef_to_geodetic(g)
        up = wgs84.R_ecef_from_enu(lat, lon)[..., 2]
        votes.append(field.cloudy(g + (w.cloud_altitude_m / (up @ s))[:, None] * s))  # flat over a few km
    votes = np.array(votes)
    inner_ground = same.ravel() & ~got
    in_shadow, lit = inner_ground & votes.all(0), inner_ground & ~votes.any(0)
    ground_lit = w.water_albedo * spec.sun.irradiance_w_m2 * cos_i / np.pi  # the darkest lit ground
    dark = out.radiance.ravel() < 0.5 * ground_lit
    print(f"ground pixels {inner_ground.sum()}: wholly in shadow {in_shadow.sum()} ({dark[in_shadow].mean():.3f} "
          f"dark), wholly lit {lit.sum()} ({dark[lit].mean():.3f} dark)")
    assert in_shadow.sum() >= 10, "the test frame (sun 9° high) must contain cloud shadows"
    # misses only where a shadow edge passes within a cloud-grid cell (1.5 km ≈ 0.2 px) of a pixel's corner
    assert dark[in_shadow].mean() > 0.9 and dark[lit].mean() < 0.02


def test_cloud_layer_is_deterministic_in_the_seed(repo, gshhg):
    from renderlab.worlds.earth.plan import EarthPlan

    def cloud_faces(seed):
        sc, _ = earth_scenario(repo, "camera.width=64", "camera.height=64", "trajectory.frames=1",
                               f"world.cloud_cover={COVER}", f"world.seed={seed}", "world.cloud_grid=96")
        plan = EarthPlan.from_scenario(sc)
        return plan._cloud_body(0)

    a, b, c = cloud_faces(3), cloud_faces(3), cloud_faces(4)
    assert np.array_equal(a.faces, b.faces) and np.array_equal(a.vertices, b.vertices)
    assert not np.array_equal(a.faces, c.faces), "another seed, another cloud field"
