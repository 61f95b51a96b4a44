"""The Dr.Jit BSDF plugins (renderlab.render.mitsuba_bsdf) against the numpy reference laws."""

import math
import zlib

import numpy as np
import pytest

from renderlab import photometry as ph
from renderlab.errors import UserError

pytest.importorskip("mitsuba")
pytest.importorskip("drjit")

from renderlab.render.mitsuba_bsdf import bsdf_dict, register_bsdfs  # noqa: E402

N = 4000
RTOL = 1e-3

CASES = [
    ("lambert", {}, 0.3),
    ("lommel_seeliger", {}, 0.3),
    ("mcewen", {}, 0.12),
    ("mcewen", {"alpha0": 0.4, "ls_weight": 1.0}, 0.12),
    ("hapke", {}, ph.C_TYPE_SINGLE_SCATTERING_ALBEDO),
    ("hapke", {"theta_bar": 0.0}, 0.6),
    ("hapke", {"theta_bar": math.radians(40), "b": 0.3, "c": 0.4, "b0": 1.0, "h": 0.05}, 0.95),
]
IDS = [f"{name}-{i}" for i, (name, _, _) in enumerate(CASES)]


@pytest.fixture(scope="module")
def mi():
    from renderlab.render.variant import init_mitsuba

    mod = init_mitsuba("llvm_ad_mono")
    register_bsdfs(mod)
    register_bsdfs(mod)  # idempotent
    return mod


@pytest.fixture(scope="module")
def dr(mi):
    import drjit

    return drjit


def upper_hemisphere(rng, n, zmin=1e-3):
    z = rng.uniform(zmin, 1.0, n)
    phi = rng.uniform(0, 2 * np.pi, n)
    s = np.sqrt(1 - z * z)
    return np.stack([s * np.cos(phi), s * np.sin(phi), z], axis=1).astype(np.float32)


def vec(mi, a):
    return mi.Vector3f(a[:, 0], a[:, 1], a[:, 2])


def flat(x):
    return np.asarray(x, dtype=np.float64).reshape(-1)


def interaction(mi, dr, wi, uv=None):
    si = dr.zeros(mi.SurfaceInteraction3f, len(wi))
    si.wi = vec(mi, wi)
    if uv is not None:
        si.uv = mi.Point2f(uv[:, 0], uv[:, 1])
    return si


def reference(law, wi, wo, albedo):
    """numpy law at the float32 directions handed to Mitsuba (wi -> camera, wo -> sun)."""
    mu0, mu, g = ph.angles_from_vectors(np.array([0.0, 0.0, 1.0]), wo.astype(np.float64), wi.astype(np.float64))
    return law.radiance_factor(mu0, mu, g, albedo)


@pytest.mark.parametrize("name, params, albedo", CASES, ids=IDS)
def test_eval_matches_numpy_reference(mi, dr, name, params, albedo):
    rng = np.random.default_rng(zlib.crc32(repr((name, params)).encode()))
    wi, wo = upper_hemisphere(rng, N), upper_hemisphere(rng, N)
    law = ph.make_law(name, **params)
    bsdf = mi.load_dict(bsdf_dict(law, albedo))
    value = flat(bsdf.eval(mi.BSDFContext(), interaction(mi, dr, wi), vec(mi, wo)))
    ref = reference(law, wi, wo, albedo)
    assert np.all(ref > 0)
    rel = np.abs(value - ref) / ref
    print(f"{name} {params}: max rel diff {rel.max():.2e} over {N} geometries")
    assert rel.max() <= RTOL


@pytest.mark.parametrize("name, params, albedo", CASES, ids=IDS)
def test_zero_below_horizon(mi, dr, name, params, albedo):
    rng = np.random.default_rng(11)
    up, down = upper_hemisphere(rng, 200), upper_hemisphere(rng, 200) * np.float32([1, 1, -1])
    bsdf = mi.load_dict(bsdf_dict(ph.make_law(name, **params), albedo))
    ctx = mi.BSDFContext()
    for wi, wo in ((up, down), (down, up), (down, down)):
        si = interaction(mi, dr, wi)
        assert np.all(flat(bsdf.eval(ctx, si, vec(mi, wo))) == 0.0)
        assert np.all(flat(bsdf.pdf(ctx, si, vec(mi, wo))) == 0.0)
    si = interaction(mi, dr, down)
    bs, weight = bsdf.sample(ctx, si, mi.Float(np.full(200, 0.5, np.float32)), mi.Point2f(*rng.random((2, 200))))
    assert np.all(flat(weight) == 0.0)


@pytest.mark.parametrize("name, params, albedo", CASES, ids=IDS)
def test_sample_weight_is_eval_over_pdf(mi, dr, name, params, albedo):
    rng = np.random.default_rng(12)
    n = 2000
    wi = upper_hemisphere(rng, n)
    bsdf = mi.load_dict(bsdf_dict(ph.make_law(name, **params), albedo))
    ctx, si = mi.BSDFContext(), interaction(mi, dr, wi)
    u2 = rng.random((2, n)).astype(np.float32)
    bs, weight = bsdf.sample(ctx, si, mi.Float(rng.random(n).astype(np.float32)), mi.Point2f(u2[0], u2[1]))
    wo = np.stack([flat(bs.wo.x), flat(bs.wo.y), flat(bs.wo.z)], axis=1)
    ok = wo[:, 2] > 1e-4
    assert ok.mean() > 0.99
    value, pdf = (flat(x) for x in bsdf.eval_pdf(ctx, si, bs.wo))
    np.testing.assert_allclose(flat(bs.pdf)[ok], pdf[ok], rtol=1e-5)
    np.testing.assert_allclose(pdf[ok], wo[ok, 2] / np.pi, rtol=1e-5)
    np.testing.assert_allclose(flat(weight)[ok], value[ok] / pdf[ok], rtol=1e-4)
    np.testing.assert_allclose(value, flat(bsdf.eval(ctx, si, bs.wo)), rtol=0, atol=0)
    assert np.all(flat(bs.sampled_type) == int(mi.BSDFFlags.DiffuseReflection))
    if name == "lambert":
        np.testing.assert_allclose(flat(weight)[ok], albedo, rtol=1e-5)


def test_flags(mi):
    bsdf = mi.load_dict(bsdf_dict(ph.make_law("mcewen"), 0.1))
    assert bsdf.flags() == int(mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.FrontSide)
    assert bsdf.component_count() == 1


@pytest.mark.parametrize("name", ["lambert", "mcewen", "hapke"])
def test_bitmap_albedo_texture(mi, dr, name):
    # 3 x 4 map; bitmap rows run along v (row 0 at v = 0), columns along u.
    amap = (np.arange(12, dtype=np.float32).reshape(3, 4) + 1.0) / 16.0
    rows, cols = np.meshgrid(np.arange(3), np.arange(4), indexing="ij")
    uv = np.stack([(cols.ravel() + 0.5) / 4, (rows.ravel() + 0.5) / 3], axis=1).astype(np.float32)
    expected_albedo = amap[rows.ravel(), cols.ravel()].astype(np.float64)
    law = ph.make_law(name)
    rng = np.random.default_rng(13)
    wi, wo = upper_hemisphere(rng, 12, zmin=0.2), upper_hemisphere(rng, 12, zmin=0.2)
    ref = reference(law, wi, wo, expected_albedo)
    texture = {"type": "bitmap", "bitmap": mi.Bitmap(amap[:, :, None]), "raw": True, "filter_type": "nearest"}
    for albedo in (texture, amap):  # nested texture dict, and a numpy map turned into a bitmap by bsdf_dict
        bsdf = mi.load_dict(bsdf_dict(law, albedo))
        value = flat(bsdf.eval(mi.BSDFContext(), interaction(mi, dr, wi, uv), vec(mi, wo)))
        np.testing.assert_allclose(value, ref, rtol=RTOL)
        params = mi.traverse(bsdf)
        assert "albedo.data" in params


def test_traverse_exposes_albedo(mi, dr):
    bsdf = mi.load_dict(bsdf_dict(ph.make_law("hapke"), 0.05))
    params = mi.traverse(bsdf)
    assert "albedo.value" in params
    wi = np.array([[0.0, 0.6, 0.8]], np.float32)
    wo = np.array([[0.0, 0.0, 1.0]], np.float32)
    before = flat(bsdf.eval(mi.BSDFContext(), interaction(mi, dr, wi), vec(mi, wo)))
    params["albedo.value"] = 0.5
    params.update()
    after = flat(bsdf.eval(mi.BSDFContext(), interaction(mi, dr, wi), vec(mi, wo)))
    law = ph.make_law("hapke")
    np.testing.assert_allclose(before, reference(law, wi, wo, 0.05), rtol=RTOL)
    np.testing.assert_allclose(after, reference(law, wi, wo, 0.5), rtol=RTOL)


@pytest.mark.parametrize("name, params, albedo", CASES[::2], ids=IDS[::2])
def test_render_radiance_is_irradiance_times_r(mi, name, params, albedo):
    """End to end: orthographic camera, directional sun of irradiance E, flat plate: L = E * r."""
    e_sun = 3.0
    to_sun = np.array([math.sin(0.7), 0.0, math.cos(0.7)])
    to_cam = np.array([math.sin(0.5) * math.cos(2.0), math.sin(0.5) * math.sin(2.0), math.cos(0.5)])
    law = ph.make_law(name, **params)
    t = mi.ScalarTransform4f
    scene = mi.load_dict(
        {
            "type": "scene",
            "integrator": {"type": "direct"},
            "sensor": {
                "type": "orthographic",
                "to_world": t().look_at(origin=(5 * to_cam).tolist(), target=[0, 0, 0], up=[0, 0, 1]) @ t().scale(0.3),
                "film": {"type": "hdrfilm", "width": 6, "height": 6, "pixel_format": "luminance"},
                "sampler": {"type": "independent", "sample_count": 2},
            },
            "plate": {"type": "rectangle", "to_world": t().scale(4.0), "bsdf": bsdf_dict(law, albedo)},
            "sun": {"type": "directional", "direction": (-to_sun).tolist(), "irradiance": e_sun},
        }
    )
    image = flat(mi.render(scene))
    mu0, mu, g = ph.angles_from_vectors([0, 0, 1], to_sun, to_cam)
    expected = e_sun * float(law.radiance_factor(mu0, mu, g, albedo))
    np.testing.assert_allclose(image, expected, rtol=RTOL)


def test_bsdf_dict_shape_and_errors(mi):
    d = bsdf_dict(ph.make_law("mcewen", alpha0=0.5), 0.2)
    assert d == {"type": "rl_mcewen", "albedo": 0.2, "alpha0": 0.5, "ls_weight": 2.0}
    d = bsdf_dict(ph.make_law("hapke", b=0.2, c=0.3), 0.1)
    assert d["type"] == "rl_hapke" and d["b"] == 0.2 and d["c"] == 0.3 and "xi" in d
    with pytest.raises(UserError, match=r"hapke albedo must be in \[0, 1\]"):
        bsdf_dict(ph.make_law("hapke"), 1.5)
    with pytest.raises(UserError, match="albedo must be a number"):
        bsdf_dict(ph.make_law("lambert"), "grey")
    with pytest.raises(UserError, match="needs a 'type' key"):
        bsdf_dict(ph.make_law("lambert"), {"value": 0.3})
    with pytest.raises(UserError, match="albedo map must have shape"):
        bsdf_dict(ph.make_law("lambert"), np.ones((2, 2, 3)))
    with pytest.raises(UserError, match="expected a PhotometricLaw"):
        bsdf_dict("lambert", 0.3)


def test_plugin_property_errors(mi):
    with pytest.raises(Exception, match="property 'albedo' is required"):
        mi.load_dict({"type": "rl_lambert"})
    with pytest.raises(Exception, match="mcewen.alpha0 must be in"):
        mi.load_dict({"type": "rl_mcewen", "albedo": 0.1, "alpha0": 60.0})
    with pytest.raises(Exception, match="unreferenced property"):
        mi.load_dict({"type": "rl_hapke", "albedo": 0.1, "theta": 0.3})
