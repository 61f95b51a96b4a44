"""EV5 world: body shape vs the radar shape, site/patch consistency, maplets vs independently
resampled truth (Mitsuba ray casts), catalog files, user shape models, seeds."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from renderlab.errors import UserError

TINY_WORLD = {
    "kind": "ev5", "seed": 11, "facet_m": 4.0,
    "site": {"extent_m": 30.0, "cell_m": 0.05, "taper_m": 1.0, "crater_max_m": 3.0, "boulder_min_m": 0.3},
    "landmarks": [{"name": "regional", "count": 10, "spacing_m": 0.2, "size": 21, "radius_m": 5.5},
                  {"name": "site", "count": 10, "spacing_m": 0.1, "size": 21, "radius_m": 2.5}],
}


def world_cfg(**over):
    from renderlab.worlds.ev5.config import EV5World

    d = copy.deepcopy(TINY_WORLD)
    d.update(over)
    return EV5World.model_validate(d)


@pytest.fixture(scope="module")
def model():
    from renderlab.worlds.ev5 import build_model

    return build_model(world_cfg(), ".")


def _volume(v, f):
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    return np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0


def test_body_matches_radar_shape():
    """Extents within ±10 % of 420 × 410 × 390 m, volume-equivalent diameter ≈ 400 m (Busch et al. 2011)."""
    from renderlab.worlds.ev5 import stream
    from renderlab.worlds.ev5.shape import procedural_shape

    cfg = world_cfg()
    shape = procedural_shape(cfg, stream(cfg.seed, "shape"))
    ext = shape.vertices.max(0) - shape.vertices.min(0)
    assert np.all(np.abs(ext / np.array([420.0, 410.0, 390.0]) - 1) < 0.10), ext
    d_eq = (6 * _volume(shape.vertices, shape.faces) / np.pi) ** (1 / 3)
    assert abs(d_eq - 400.0) < 20.0, d_eq
    assert ext[2] < min(ext[0], ext[1])  # oblate
    # closed, outward: every edge shared by exactly two facets with opposite directions
    e = np.concatenate([shape.faces[:, [0, 1]], shape.faces[:, [1, 2]], shape.faces[:, [2, 0]]])
    fwd = set(map(tuple, e.tolist()))
    assert all((b, a) in fwd for a, b in e[:2000].tolist())


def test_site_meets_global_and_global_stays_below(model):
    """The patch border lies on the global mesh; inside the patch no global facet pokes through it."""
    site, shape = model.site, model.shape
    vs = site.to_site(shape.vertices)
    tri = vs[shape.faces]
    pts = np.concatenate([vs, tri.mean(1), (tri[:, 0] + tri[:, 1]) / 2, (tri[:, 1] + tri[:, 2]) / 2])
    half = site.extent_m / 2
    inside = (np.abs(pts[:, 0]) < half - 0.05) & (np.abs(pts[:, 1]) < half - 0.05) & (np.abs(pts[:, 2]) < 50)
    assert inside.sum() > 20
    h_site = site.height_at(pts[inside, 0], pts[inside, 1])
    # where the two surfaces coincide (the outer strip) they differ by the DEM's corner cutting (mm)
    assert np.all(pts[inside, 2] <= h_site + 0.005), np.max(pts[inside, 2] - h_site)
    # deeper than the outer strip (1.5 facets) plus a facet the global facets are cut; next to it, lowered
    d_edge = half - np.maximum(np.abs(pts[inside, 0]), np.abs(pts[inside, 1]))
    deep = d_edge > 1.5 * 4.0 + 1.5 * 4.0
    assert deep.sum() == 0  # cut away
    assert np.any(pts[inside, 2] < h_site - 0.05)  # lowered
    # features: boulders, craters, the target boulder stands ≥ 0.5 m above its surroundings
    assert site.n_boulders > 10 and site.n_craters > 5
    assert site.height_at(0.0, 0.0) - site.height_at(3.0, 3.0) > 0.5


def test_maplets_error_rms_against_mitsuba_resampled_truth(model):
    """Maplet heights − truth heights (resampled by casting Mitsuba rays along −z of each maplet onto
    the site mesh, k × k rays per maplet cell, averaged) have the configured rms to within 10 %."""
    from renderlab.render.mitsuba_backend import MitsubaBackend
    from renderlab.render.scene import RenderSettings, SceneDescription

    site_body = model.bodies()[1]
    backend = MitsubaBackend(SceneDescription(bodies=[site_body]), RenderSettings())
    mi = backend.mi
    diffs = []
    for m in model.maplets:
        k = int(min(8, max(1, round(m.spacing_m / model.site.cell_m))))
        x, y = m.grid_xy()
        sub = ((np.arange(k) + 0.5) / k - 0.5) * m.spacing_m
        U, V = np.broadcast_arrays(x[None, :, None, None] + sub[None, None, None, :],
                                   y[:, None, None, None] + sub[None, None, :, None])
        top = m.to_body(np.stack([U, V, np.full(U.shape, 20.0)], -1)).reshape(-1, 3)
        d = -m.R_body_from_maplet[:, 2]
        ray = mi.Ray3f(mi.Point3f(*[top[:, i].astype(np.float32) for i in range(3)]),
                       mi.Vector3f(*[np.full(len(top), d[i], np.float32) for i in range(3)]))
        si = backend.scene.ray_intersect(ray)
        assert np.all(np.array(si.is_valid()))
        h_truth = 20.0 - np.array(si.t, dtype=np.float64).reshape(U.shape).mean(axis=(2, 3))
        diffs.append((m.heights_m - h_truth).ravel())
    rms = float(np.sqrt(np.mean(np.concatenate(diffs) ** 2)))
    assert abs(rms / 0.03 - 1) < 0.10, rms


def test_zero_mapping_error_reproduces_truth_cell_means():
    """With mapping_error_m = 0 the maplets are the truth cell means (differences ≪ 3 cm)."""
    from renderlab.worlds.ev5 import build_model
    from renderlab.worlds.ev5.landmarks import truth_heights

    cfg = world_cfg(mapping_error_m=0.0, albedo_error_rms=0.0,
                    landmarks=[{"name": "a", "count": 3, "spacing_m": 0.2, "size": 5, "radius_m": 4.0}])
    mdl = build_model(cfg, ".")
    m = mdl.maplets[0]
    assert abs(truth_heights(mdl.site, m.center_m, m.R_body_from_maplet, np.zeros(1), np.zeros(1))[0]) < 1e-9
    assert np.all(np.abs(m.heights_m) < 1.0)  # heights are relative to the landmark's own plane
    assert np.std(m.heights_m) > 0  # and not flat: it carries the terrain


def test_same_seed_same_world_other_seed_differs(model):
    from renderlab.worlds.ev5 import build_model

    again = build_model(world_cfg(), ".")
    assert np.array_equal(again.shape.vertices, model.shape.vertices)
    assert np.array_equal(again.site.heights_m, model.site.heights_m)
    assert np.array_equal(again.site.albedo, model.site.albedo)
    for a, b in zip(again.maplets, model.maplets):
        assert np.array_equal(a.heights_m, b.heights_m) and np.array_equal(a.center_m, b.center_m)
    other = build_model(world_cfg(seed=12), ".")
    assert not np.array_equal(other.site.heights_m, model.site.heights_m)


def test_catalog_round_trip_and_errors(model, tmp_path):
    from renderlab.truthset import TruthSetWriter
    from renderlab.worlds.ev5.catalog import read_catalog, write_catalog

    out = tmp_path / "set"
    with TruthSetWriter(out, {"renderer": {"name": "none"}}) as w:
        write_catalog(w, model.maplets, model.tiers)
    back = read_catalog(out)
    assert [m.landmark_id for m in back] == [m.landmark_id for m in model.maplets]
    for a, b in zip(back, model.maplets):
        assert np.allclose(a.center_m, b.center_m, atol=0, rtol=0)
        assert np.allclose(a.R_body_from_maplet, b.R_body_from_maplet, atol=1e-12)
        assert np.allclose(a.heights_m, b.heights_m, atol=1e-6) and np.allclose(a.albedo, b.albedo, atol=1e-6)
    (out / "maplets" / "000001.exr").write_bytes(b"not an exr")
    with pytest.raises(UserError, match="000001.exr"):
        read_catalog(out)
    (out / "landmarks.parquet").unlink()
    with pytest.raises(UserError, match="landmarks.parquet"):
        read_catalog(out)


def _write_shapes(tmp_path, v_km, f):
    obj = tmp_path / "s.obj"
    obj.write_text("".join(f"v {a} {b} {c}\n" for a, b, c in v_km) + "".join(f"f {a+1} {b+1} {c+1}\n" for a, b, c in f))
    ply = tmp_path / "s.ply"
    head = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(v_km)}\nproperty float x\nproperty float y\n"
            f"property float z\nelement face {len(f)}\nproperty list uchar int vertex_indices\nend_header\n").encode()
    body = np.asarray(v_km, "<f4").tobytes() + b"".join(np.uint8(3).tobytes() + np.asarray(t, "<i4").tobytes() for t in f)
    ply.write_bytes(head + body)
    return obj, ply


def test_user_shape_models_replace_the_procedural_body(tmp_path):
    """OBJ, binary PLY and Gaskell ICQ models load (km → m, outward faces) and carry a site."""
    from renderlab.worlds.ev5.shape import icosphere, load_shape_file
    from renderlab.worlds.ev5 import build_model

    u, f = icosphere(6)
    v_km = u * np.array([0.21, 0.2, 0.19])
    obj, ply = _write_shapes(tmp_path, v_km, f[:, ::-1])  # inward winding on purpose
    q = 48  # ICQ: 6 cube faces of (q+1)² vertices projected on the same ellipsoid
    t = np.linspace(-1, 1, q + 1)
    A, B = np.meshgrid(t, t)
    ex, ey, ez = np.eye(3)
    npq = [(ex, ey, ez), (-ex, ez, ey), (ey, ez, ex), (-ey, ex, ez), (ez, ex, ey), (-ez, ey, ex)]  # P × Q = N
    faces = [N + A[..., None] * P + B[..., None] * Q for N, P, Q in npq]
    cube = np.stack(faces)
    pts = cube / np.linalg.norm(cube, axis=-1, keepdims=True) * np.array([0.21, 0.2, 0.19])
    icq = tmp_path / "s.icq"
    icq.write_text(f"{q}\n" + "".join(f"{a:.9f} {b:.9f} {c:.9f}\n" for a, b, c in pts.reshape(-1, 3)))
    vol_true = 4 / 3 * np.pi * 210 * 200 * 190
    site_cfg = {"extent_m": 40.0, "cell_m": 0.1, "taper_m": 1.0, "crater_max_m": 2.0, "boulder_min_m": 0.3}
    tiers = [{"name": "a", "count": 3, "spacing_m": 0.2, "size": 11, "radius_m": 3.0}]
    for path in (obj, ply, icq):
        shape = load_shape_file(path, "km")
        assert shape.volume() > 0, path.name
        assert abs(shape.volume() / vol_true - 1) < 0.03, path.name
        mdl = build_model(world_cfg(shape_file=path.name, site=site_cfg, landmarks=tiers), tmp_path)
        assert mdl.site.n == 401 and np.isfinite(mdl.site.heights_m).all()
        assert len(mdl.maplets) == 3
    bad = tmp_path / "bad.obj"
    bad.write_text("v 0 0 0\nf 1 2 3\n")
    with pytest.raises(UserError, match="bad.obj"):
        load_shape_file(bad, "km")
    with pytest.raises(UserError, match="not found"):
        load_shape_file(tmp_path / "missing.ply", "km")


def test_shadow_test_agrees_with_mitsuba_shadow_rays(model):
    """The numba DEM ray march (shadow_fraction) vs Mitsuba ray_test against the site mesh, for the
    footprint points of every maplet under a low sun (25° elevation): ≥ 97 % of points agree."""
    from renderlab.render.mitsuba_backend import MitsubaBackend
    from renderlab.render.scene import RenderSettings, SceneDescription
    from renderlab.worlds.ev5.landmark_truth import footprint_points, local_lit, shadowed

    site = model.site
    backend = MitsubaBackend(SceneDescription(bodies=[model.bodies()[1]]), RenderSettings())
    mi = backend.mi
    el, az = np.radians(25.0), np.radians(200.0)
    sun = site.R_body_from_site @ np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    pts = np.concatenate([footprint_points(site, m, 9) for m in model.maplets])
    lit = local_lit(site, pts, sun)  # facing the sun; the cast-shadow test is compared on these
    pts = pts[lit]
    ours = shadowed(site, pts, sun)
    o = pts + 2e-3 * sun + 1e-3 * site.R_body_from_site[:, 2]
    ray = mi.Ray3f(mi.Point3f(*[o[:, i].astype(np.float32) for i in range(3)]),
                   mi.Vector3f(*[np.full(len(o), sun[i], np.float32) for i in range(3)]))
    theirs = np.array(backend.scene.ray_test(ray), dtype=bool)
    assert 0.02 < theirs.mean() < 0.98  # the scene has both lit and shadowed points
    assert np.mean(ours == theirs) >= 0.97, (ours.mean(), theirs.mean(), np.mean(ours == theirs))


@pytest.mark.parametrize("over, match", [
    ({"landmarks": [{"name": "a", "count": 3, "spacing_m": 0.2, "size": 31, "radius_m": 14.0}]}, "does not fit"),
    ({"landmarks": [{"name": "a", "count": 3, "spacing_m": 0.01, "size": 31, "radius_m": 2.0}]}, "finer than the site"),
    ({"landmarks": [{"name": "a", "count": 3, "spacing_m": 0.2, "size": 30, "radius_m": 2.0}]}, "odd"),
    ({"site": {"target_boulder_m": 5.0}}, "target_boulder_m"),
    ({"site": {"extent_m": 0.5}}, "extent_m"),
])
def test_bad_world_keys_are_user_errors(over, match):
    from renderlab.scenario import scenario_from_dict

    world = copy.deepcopy(TINY_WORLD)
    world.update(over)
    with pytest.raises(UserError, match=match):
        scenario_from_dict({"world": world, "trajectory": {"kind": "ev5_descent"}})


def test_descent_trajectory_keys_are_checked():
    from renderlab.scenario import scenario_from_dict

    for traj, match in (({"waypoint_altitude_m": 2000.0}, "altitudes must decrease"),
                        ({"altitudes_m": [2.0]}, "outside"), ({"phase_deg": 95.0}, "phase_deg")):
        with pytest.raises(UserError, match=match):
            scenario_from_dict({"world": copy.deepcopy(TINY_WORLD), "trajectory": {"kind": "ev5_descent", **traj}})


def test_descent_sampling_by_rate_and_by_altitude():
    """3 Hz bursts are 1/3 s apart; default sampling spreads frames geometrically in altitude from
    start to final; the altitude profile passes the waypoints at their times."""
    from renderlab.dynamics.small_body import SpinState
    from renderlab.worlds.ev5.config import EV5DescentTrajectory
    from renderlab.worlds.ev5.descent import DescentProfile, descent_states

    o, R = np.array([150.0, 80.0, 60.0]), np.eye(3)
    rate = descent_states(EV5DescentTrajectory(sampling="rate", frames=5, start_time_s=1400.0), SpinState(), o, R)
    assert np.allclose(np.diff([s.time_s for s in rate]), 1 / 3.0)
    alt = descent_states(EV5DescentTrajectory(frames=7), SpinState(), o, R)
    h = np.array([s.altitude_m for s in alt])
    assert np.allclose(h, np.geomspace(1000.0, 5.0, 7), rtol=1e-9)
    p = DescentProfile(EV5DescentTrajectory())
    assert np.allclose(p.altitude([0.0, 900.0, 1500.0, 1500.0 + 450.0]), [1000.0, 200.0, 50.0, 5.0])
