"""EV5 world: body shape vs the radar shape, site/patch consistency, maplets vs independently
resampled truth (Mitsuba ray casts), catalog files, user shape models, seeds."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from tiny_ev5 import TINY_WORLD

from renderlab.errors import UserError


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


def _radius_residuals(cfg):
    """Mesh vertex radius − the reference ellipsoid (semi-axes size/2 − ridge, size/2 − ridge, size/2),
    with each vertex's latitude and angle from the concavity centre (deg)."""
    from renderlab.worlds.ev5 import stream
    from renderlab.worlds.ev5.shape import procedural_shape

    v = procedural_shape(cfg, stream(cfg.seed, "shape")).vertices
    r = np.linalg.norm(v, axis=1)
    u = v / r[:, None]
    a, b, c = np.asarray(cfg.size_m) / 2
    ell = 1 / np.sqrt((u[:, 0] / (a - cfg.ridge_height_m)) ** 2 + (u[:, 1] / (b - cfg.ridge_height_m)) ** 2
                      + (u[:, 2] / c) ** 2)
    lat, lon = np.radians(cfg.concavity_lat_deg), np.radians(cfg.concavity_lon_deg)
    u_cav = np.array([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)])
    return r - ell, np.degrees(np.arcsin(u[:, 2])), np.degrees(np.arccos(np.clip(u @ u_cav, -1, 1)))


@pytest.mark.parametrize("features", [True, False])
def test_body_has_an_equatorial_ridge_and_a_150_m_concavity(features):
    """The mesh stands ≥ 4 m (half the 8 m ridge) higher on the equator than at mid-latitudes, and is
    ≥ 7.5 m (half the 15 m depth) lower inside the central third of the 150 m concavity than in a ring
    around it; with ridge_height_m = concavity_depth_m = 0 neither signature is there (< 3 m)."""
    cfg = world_cfg() if features else world_cfg(ridge_height_m=0.0, concavity_depth_m=0.0)
    res, lat, theta = _radius_residuals(cfg)
    theta_c = np.degrees(75.0 / np.cbrt(np.prod(np.asarray(cfg.size_m) / 2)))  # 150 m diameter, in angle
    ridge = res[np.abs(lat) < 3].mean() - res[(np.abs(lat) > 30) & (np.abs(lat) < 60)].mean()
    bowl = res[theta < theta_c / 3].mean() - res[(theta > 1.2 * theta_c) & (theta < 2 * theta_c)].mean()
    if features:
        assert ridge > 4.0 and bowl < -7.5, (ridge, bowl)
    else:
        assert abs(ridge) < 3.0 and abs(bowl) < 3.0, (ridge, bowl)


def test_default_photometry_is_a_dark_c_type():
    """The world's default Hapke law (Mathilde parameters, w = 0.085) has a normal albedo π r(0°, 0°, 0°)
    of ≈ 0.10 (C-type), and the spin state is retrograde with P = 3.725 h, pole (180°, −84°)."""
    from renderlab.dynamics.small_body import SpinState
    from renderlab.photometry import make_law

    cfg = world_cfg()
    law = make_law(cfg.law, **cfg.law_params)
    a_n = float(np.pi * law.radiance_factor(np.array([1.0]), np.array([1.0]), np.array([0.0]), cfg.albedo)[0])
    assert 0.08 < a_n < 0.12, a_n
    spin = SpinState(cfg.pole_lambda_deg, cfg.pole_beta_deg, cfg.rotation_period_h * 3600.0)
    assert spin.retrograde and spin.period_s == pytest.approx(13410.0)
    assert (cfg.pole_lambda_deg, cfg.pole_beta_deg) == (180.0, -84.0)


def test_boulder_and_crater_sizes_follow_the_power_law():
    """Sizes drawn for the site follow the truncated cumulative power law N(>D) ∝ D^−α (scipy KS test
    against its analytic CDF) and their number is Poisson about density · area · (D_min^−α − D_max^−α)."""
    from scipy import stats

    from renderlab.worlds.ev5.terrain import power_law_diameters

    rng = np.random.default_rng(4)
    for density, area, slope, d_min, d_max in ((0.02, 3600.0, 3.0, 0.15, 2.0), (0.01, 40000.0, 2.0, 0.3, 8.0)):
        d = power_law_diameters(rng, density, area, slope, d_min, d_max)
        lo, hi = d_min ** -slope, d_max ** -slope
        expected = density * area * (lo - hi)
        assert abs(len(d) - expected) < 4 * np.sqrt(expected), (len(d), expected)
        assert d.min() >= d_min and d.max() <= d_max

        def cdf(x, lo=lo, hi=hi, d_min=d_min, d_max=d_max, slope=slope):
            return (lo - np.clip(x, d_min, d_max) ** -slope) / (lo - hi)

        p = stats.kstest(d, cdf).pvalue
        assert p > 1e-3, p
        # and not the wrong slope: the same sample against α + 0.3 is rejected
        lo2, hi2 = d_min ** -(slope + 0.3), d_max ** -(slope + 0.3)

        def wrong(x, lo2=lo2, hi2=hi2, d_min=d_min, d_max=d_max, slope=slope):
            return (lo2 - np.clip(x, d_min, d_max) ** -(slope + 0.3)) / (lo2 - hi2)

        assert stats.kstest(d, wrong).pvalue < 1e-6


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


def _mitsuba_truth_differences(mdl) -> np.ndarray:
    """Maplet heights − truth heights resampled independently: Mitsuba rays cast along −z of each maplet
    onto the site mesh from 20 m above, k × k rays per maplet cell (k = spacing / site cell), averaged."""
    from renderlab.render.mitsuba_backend import MitsubaBackend
    from renderlab.render.scene import RenderSettings, SceneDescription

    backend = MitsubaBackend(SceneDescription(bodies=[mdl.bodies()[1]]), RenderSettings())
    mi = backend.mi
    diffs = []
    for m in mdl.maplets:
        k = int(min(8, max(1, round(m.spacing_m / mdl.site.cell_m))))
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
    return np.concatenate(diffs)


def test_maplets_error_rms_against_mitsuba_resampled_truth(model):
    """Maplet heights − truth heights (resampled by Mitsuba ray casts, :func:`_mitsuba_truth_differences`)
    have the configured rms (default 3 cm) to within 10 %."""
    rms = float(np.sqrt(np.mean(_mitsuba_truth_differences(model) ** 2)))
    assert abs(rms / 0.03 - 1) < 0.10, rms


@pytest.mark.parametrize("error_m, corr_cells", [(0.01, 0.0), (0.0, 1.0)])
def test_mapping_error_is_settable_and_truth_resampling_is_exact(error_m, corr_cells):
    """A settable mapping error: 1 cm white error gives 1 cm rms (±10 %); with no error the maplets are the
    truth cell means to float32 ray-cast precision everywhere, boulder flanks included (< 0.5 mm)."""
    from renderlab.worlds.ev5 import build_model

    d = _mitsuba_truth_differences(build_model(world_cfg(mapping_error_m=error_m,
                                                         mapping_error_corr_cells=corr_cells), "."))
    rms = float(np.sqrt(np.mean(d ** 2)))
    if error_m > 0:
        assert abs(rms / error_m - 1) < 0.10, rms
    else:
        assert np.abs(d).max() < 5e-4, (rms, np.abs(d).max())


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
    from renderlab.files.truthset import TruthSetWriter
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
    # ASCII PLY with a comment and an extra vertex property before x
    aply = tmp_path / "a.ply"
    lines = [f"{0.5} {a:.9f} {b:.9f} {c:.9f}" for a, b, c in v_km] + [f"3 {a} {b} {c}" for a, b, c in f]
    aply.write_text(f"ply\nformat ascii 1.0\ncomment renderlab test\nelement vertex {len(v_km)}\nproperty float confidence\n"
                    f"property double x\nproperty double y\nproperty double z\nelement face {len(f)}\n"
                    "property list uchar int vertex_indices\nend_header\n" + "\n".join(lines) + "\n")
    return obj, ply, aply


def _gaskell_icq(path, q, semi_axes_km):
    """An ICQ file in Gaskell's layout (SHAPE.TXT): face 0 = +z, 1..4 = +x, +y, −x, −y, 5 = −z; vertex
    (i, j, f) at N_f + a_i P_f + b_j Q_f on the cube (i fastest), projected on an ellipsoid."""
    t = np.linspace(-1, 1, q + 1)
    A, B = np.meshgrid(t, t)  # A along i (columns), B along j (rows)
    x, y, z = np.eye(3)
    npq = [(z, -y, x), (x, -y, -z), (y, x, -z), (-x, y, -z), (-y, -x, -z), (-z, -y, -x)]
    cube = np.stack([N + A[..., None] * P + B[..., None] * Q for N, P, Q in npq])  # [f, j, i]
    # the test data follows SHAPE.TXT's shared-edge identities, e.g. v(I,0,2) = v(0,I,0), v(Q,I,4) = v(0,I,3)
    assert np.allclose(cube[2, 0, :], cube[0, :, 0]) and np.allclose(cube[4, :, q], cube[3, :, 0])
    assert np.allclose(cube[5, q, :], cube[3, q, ::-1]) and np.allclose(cube[4, 0, :], cube[0, ::-1, q])
    pts = cube / np.linalg.norm(cube, axis=-1, keepdims=True) * np.asarray(semi_axes_km)
    path.write_text(f"{q:>10d}\n" + "".join(f"{a:15.5f}{b:15.5f}{c:15.5f}\n" for a, b, c in pts.reshape(-1, 3)))
    return path


def test_user_shape_models_replace_the_procedural_body(tmp_path):
    """OBJ, binary and ASCII PLY and Gaskell ICQ models load (km → m) as closed meshes with outward faces,
    the volume of the ellipsoid they sample (to 3 %), and carry a site and a catalog."""
    from renderlab.worlds.ev5 import build_model
    from renderlab.worlds.ev5.shape import icosphere, load_shape_file

    u, f = icosphere(6)
    v_km = u * np.array([0.21, 0.2, 0.19])
    paths = _write_shapes(tmp_path, v_km, f[:, ::-1])  # inward winding on purpose
    q = 48
    icq = _gaskell_icq(tmp_path / "s.icq", q, [0.21, 0.2, 0.19])
    vol_true = 4 / 3 * np.pi * 210 * 200 * 190
    site_cfg = {"extent_m": 40.0, "cell_m": 0.1, "taper_m": 1.0, "crater_max_m": 2.0, "boulder_min_m": 0.3}
    tiers = [{"name": "a", "count": 3, "spacing_m": 0.2, "size": 11, "radius_m": 3.0}]
    for path in (*paths, icq):
        shape = load_shape_file(path, "km")
        assert shape.volume() > 0, path.name
        assert abs(shape.volume() / vol_true - 1) < 0.03, path.name
        # closed and consistently wound: every directed edge appears once, its reverse once
        e = np.concatenate([shape.faces[:, [0, 1]], shape.faces[:, [1, 2]], shape.faces[:, [2, 0]]])
        fwd = set(map(tuple, e.tolist()))
        assert len(fwd) == len(e) and all((b, a) in fwd for a, b in e.tolist()), path.name
        # outward: facet normals point away from the centre
        tri = shape.vertices[shape.faces]
        assert np.all(np.einsum("ij,ij->i", np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), tri.mean(1)) > 0)
        if path is icq:
            assert len(shape.vertices) == 6 * q * q + 2  # shared cube-edge vertices merged
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


def test_shadow_fractions_of_a_frame_equal_each_landmark_marched_alone(model):
    """The frame's one stacked, parallel march (landmark_truth._shadow_fractions) gives each landmark exactly the
    fraction its own footprint gives point by point (low sun: some landmarks partly shadowed)."""
    from renderlab.worlds.ev5.landmark_truth import _shadow_fractions, footprint_points, local_lit, shadowed

    site = model.site
    el, az = np.radians(20.0), np.radians(120.0)
    sun = site.R_body_from_site @ np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    got = _shadow_fractions(site, model.maplets, sun, {}, 9)
    want = []
    for m in model.maplets:
        fp = footprint_points(site, m, 9)
        want.append(np.mean(shadowed(site, fp, sun) | ~local_lit(site, fp, sun)))
    assert len(got) == len(model.maplets) and np.any((np.array(want) > 0) & (np.array(want) < 1))
    np.testing.assert_array_equal(got, np.array(want))


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
