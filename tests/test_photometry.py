"""Analytic checks of the numpy photometric laws (renderlab.photometry)."""

import math

import numpy as np
import pytest
from scipy import integrate, optimize
from scipy.special import roots_legendre

from renderlab import photometry as ph
from renderlab.errors import UserError


def random_geometry(rng, n=2000, lo=1e-3):
    """Consistent (mu0, mu, g): random incidence/emission cosines and relative azimuth."""
    mu0 = rng.uniform(lo, 1.0, n)
    mu = rng.uniform(lo, 1.0, n)
    psi = rng.uniform(0.0, np.pi, n)
    cos_g = mu0 * mu + np.sqrt(1 - mu0**2) * np.sqrt(1 - mu**2) * np.cos(psi)
    return mu0, mu, np.arccos(np.clip(cos_g, -1.0, 1.0))


def hemispherical_albedo(law_fn, mu0):
    """Directional-hemispherical albedo (1/mu0) * integral of r * mu over the emission hemisphere."""
    i = math.acos(mu0)

    def integrand(phi, mu):
        cos_g = mu0 * mu + math.sin(i) * math.sqrt(1 - mu * mu) * math.cos(phi)
        g = math.acos(min(1.0, max(-1.0, cos_g)))
        return float(law_fn(mu0, mu, g)) * mu / mu0

    return integrate.dblquad(integrand, 0.0, 1.0, 0.0, 2 * math.pi, epsabs=1e-8, epsrel=1e-7)[0]


def hemispherical_albedo_gl(law_fn, mu0, n_mu=96, n_phi=128):
    """Vectorised Gauss-Legendre version of :func:`hemispherical_albedo` (for the slower laws)."""
    t, c = roots_legendre(n_mu)
    mu, c_mu = 0.5 * (t + 1.0), 0.5 * c
    t, c = roots_legendre(n_phi)
    phi, c_phi = np.pi * (t + 1.0), np.pi * c
    mm, pp = np.meshgrid(mu, phi, indexing="ij")
    cos_g = mu0 * mm + math.sqrt(1 - mu0 * mu0) * np.sqrt(1 - mm * mm) * np.cos(pp)
    r = law_fn(mu0, mm, np.arccos(np.clip(cos_g, -1.0, 1.0)))
    return float(np.einsum("i,j,ij->", c_mu, c_phi, r * mm / mu0))


def chandrasekhar_h_numerical(w, n=200):
    """Solve 1/H(x) = sqrt(1-w) + (w/2) int_0^1 x' H(x')/(x+x') dx' (isotropic scattering) on
    Gauss-Legendre nodes with scipy.optimize.root; return the Nystrom interpolant H(x)."""
    t, c = roots_legendre(n)
    x, c = 0.5 * (t + 1.0), 0.5 * c
    gamma = math.sqrt(1.0 - w)

    def residual(h):
        return h * (gamma + 0.5 * w * (c * x * h / (x[:, None] + x)).sum(axis=1)) - 1.0

    sol = optimize.root(residual, np.ones(n), method="hybr", tol=1e-13)
    assert sol.success
    h_nodes = sol.x
    return lambda xx: 1.0 / (gamma + 0.5 * w * (c * x * h_nodes / (np.asarray(xx)[..., None] + x)).sum(-1))


# ----------------------------------------------------------------------------- Lambert
def test_lambert_closed_form_and_horizon():
    rng = np.random.default_rng(1)
    mu0, mu, g = random_geometry(rng)
    a = rng.uniform(0, 1, mu0.size)
    np.testing.assert_allclose(ph.lambert(mu0, mu, g, a), a * mu0 / np.pi, rtol=1e-15)
    r = ph.lambert([-0.2, 0.5, 0.0, 0.5], [0.5, -0.1, 0.5, 0.0], 0.3, 0.5)
    assert np.all(r == 0.0)
    assert ph.lambert(1.0, 1.0, 0.0, 0.25).dtype == np.float64


@pytest.mark.parametrize("mu0", [1.0, 0.6, 0.15])
def test_lambert_hemispherical_albedo_is_A(mu0):
    a = 0.37
    assert hemispherical_albedo(lambda m0, m, g: ph.lambert(m0, m, g, a), mu0) == pytest.approx(a, rel=1e-6)
    # the Gauss-Legendre variant used for Hapke below agrees
    assert hemispherical_albedo_gl(lambda m0, m, g: ph.lambert(m0, m, g, a), mu0) == pytest.approx(a, rel=1e-10)


# ----------------------------------------------------------------------------- Lommel-Seeliger
def test_lommel_seeliger_reciprocity_and_normalisation():
    rng = np.random.default_rng(2)
    mu0, mu, g = random_geometry(rng)
    r1 = ph.lommel_seeliger(mu0, mu, g, 0.2) / mu0
    r2 = ph.lommel_seeliger(mu, mu0, g, 0.2) / mu
    np.testing.assert_allclose(r1, r2, rtol=1e-13)
    assert ph.lommel_seeliger(1.0, 1.0, 0.0, 0.2) == pytest.approx(float(ph.lambert(1.0, 1.0, 0.0, 0.2)), rel=1e-15)
    # Hapke's single-scattering term with w = 8A
    a = 0.05
    np.testing.assert_allclose(ph.lommel_seeliger(mu0, mu, g, a), 8 * a / (4 * np.pi) * mu0 / (mu0 + mu), rtol=1e-14)
    assert np.all(ph.lommel_seeliger([0.0, 0.3], [0.3, -1e-9], 0.1, 0.2) == 0.0)


# ----------------------------------------------------------------------------- McEwen
def test_mcewen_limits():
    rng = np.random.default_rng(3)
    mu0, mu, _ = random_geometry(rng)
    a = 0.12
    # beta -> 0 (g >> alpha0): Lambert
    np.testing.assert_allclose(ph.mcewen(mu0, mu, np.pi, a, alpha0=0.01), ph.lambert(mu0, mu, 0, a), rtol=1e-14)
    # beta = 1 (g = 0): Lommel-Seeliger with McEwen's c = 2
    np.testing.assert_allclose(ph.mcewen(mu0, mu, 0.0, a), ph.lommel_seeliger(mu0, mu, 0.0, a), rtol=1e-14)
    # between the two at intermediate phase
    r = ph.mcewen(mu0, mu, 1.0, a)
    lo = np.minimum(ph.lambert(mu0, mu, 1.0, a), ph.lommel_seeliger(mu0, mu, 1.0, a))
    hi = np.maximum(ph.lambert(mu0, mu, 1.0, a), ph.lommel_seeliger(mu0, mu, 1.0, a))
    assert np.all((r >= lo * (1 - 1e-12)) & (r <= hi * (1 + 1e-12)))


def test_mcewen_is_retina_eq5_with_ls_weight_1():
    rng = np.random.default_rng(4)
    n = rng.normal(size=(500, 3))
    s = n + rng.normal(size=(500, 3))  # mostly lit
    v = n + rng.normal(size=(500, 3))
    n_hat, s_hat, v_hat = (x / np.linalg.norm(x, axis=1, keepdims=True) for x in (n, s, v))
    cos_i = np.sum(n_hat * s_hat, axis=1)  # eq. 6
    cos_r = np.sum(n_hat * v_hat, axis=1)  # eq. 7
    alpha = np.arccos(np.clip(np.sum(s_hat * v_hat, axis=1), -1, 1))  # eq. 8
    alpha0 = math.radians(60)
    beta = np.exp(-alpha / alpha0)
    a_k = 0.3
    eq5 = a_k * ((1 - beta) * cos_i + beta * cos_i / (cos_i + cos_r))
    ok = (cos_i > 0) & (cos_r > 0)
    mu0, mu, g = ph.angles_from_vectors(n, s, v)
    r = ph.mcewen(mu0, mu, g, a_k, alpha0=alpha0, ls_weight=1.0)
    np.testing.assert_allclose(np.pi * r[ok], eq5[ok], rtol=1e-9)
    assert np.all(r[~ok] == 0.0)


# ----------------------------------------------------------------------------- Hapke
def test_chandrasekhar_reference_solver_matches_tables():
    # Chandrasekhar (1960), conservative isotropic scattering: H(0.5) = 2.0128, H(1) = 2.9078
    h = chandrasekhar_h_numerical(1.0)
    assert h(1.0) == pytest.approx(2.9078, abs=2e-4)
    assert h(0.5) == pytest.approx(2.0128, abs=2e-4)


@pytest.mark.parametrize("w", [0.05, 0.3, 0.6, 0.9, 0.99, 1.0])
def test_hapke2002_h_function_within_one_percent(w):
    h = chandrasekhar_h_numerical(w)
    x = np.linspace(0.0, 1.0, 201)
    err = ph.chandrasekhar_h_hapke2002(x, w) / h(x) - 1.0
    assert np.max(np.abs(err)) < 0.01


def test_hapke_isotropic_smooth_equals_chandrasekhar_solution():
    # B0 = 0, theta_bar = 0, isotropic particles: IMSA is the exact semi-infinite isotropic solution
    # r = w/(4pi) mu0/(mu0+mu) H(mu0) H(mu); only the H approximation (~1 % each) separates them.
    rng = np.random.default_rng(5)
    mu0, mu, g = random_geometry(rng, 500)
    p = ph.HapkeParams(b0=0.0, theta_bar=0.0, xi=0.0)
    for w in (0.2, 0.7, 0.98):
        h = chandrasekhar_h_numerical(w)
        exact = w / (4 * np.pi) * mu0 / (mu0 + mu) * h(mu0) * h(mu)
        np.testing.assert_allclose(ph.hapke(mu0, mu, g, w, p), exact, rtol=0.02)


def _smooth_hapke_independent(mu0, mu, g, w, b0, h, xi):
    gamma = np.sqrt(1 - w)
    r0 = (1 - gamma) / (1 + gamma)

    def hf(x):
        return 1 / (1 - w * x * (r0 + (1 - 2 * r0 * x) / 2 * np.log((1 + x) / x)))

    p = (1 - xi**2) / (1 + 2 * xi * np.cos(g) + xi**2) ** 1.5
    b = b0 / (1 + np.tan(g / 2) / h)
    return w / (4 * np.pi) * mu0 / (mu0 + mu) * ((1 + b) * p + hf(mu0) * hf(mu) - 1)


def test_hapke_zero_roughness_is_exactly_smooth_and_continuous():
    rng = np.random.default_rng(6)
    mu0, mu, g = random_geometry(rng)
    p0 = ph.HapkeParams(theta_bar=0.0)
    r0 = ph.hapke(mu0, mu, g, 0.3, p0)
    np.testing.assert_allclose(r0, _smooth_hapke_independent(mu0, mu, g, 0.3, p0.b0, p0.h, p0.xi), rtol=1e-12)
    r_tiny = ph.hapke(mu0, mu, g, 0.3, ph.HapkeParams(theta_bar=1e-4))
    np.testing.assert_allclose(r_tiny, r0, rtol=2e-3)


@pytest.mark.parametrize("theta_bar_deg", [0.0, 19.0, 45.0])
def test_hapke_reciprocity(theta_bar_deg):
    rng = np.random.default_rng(7)
    mu0, mu, g = random_geometry(rng)
    p = ph.HapkeParams(theta_bar=math.radians(theta_bar_deg), b=0.3, c=0.5)
    np.testing.assert_allclose(ph.hapke(mu0, mu, g, 0.4, p) / mu0, ph.hapke(mu, mu0, g, 0.4, p) / mu, rtol=1e-10)


def test_hapke_shadowing_bounded_and_horizon_zero():
    rng = np.random.default_rng(8)
    mu0, mu, g = random_geometry(rng)
    mu0e, mue, s = ph._rough_cosines(mu0, mu, g, math.radians(30))
    # Hapke's closed-form S is an approximation: it can exceed 1 by up to ~10 % at grazing emission.
    assert np.all(np.isfinite(s)) and np.all(s > 0) and np.all(s < 1.15)
    assert np.all(mu0e > 0) and np.all(mue > 0)
    # In the incidence-emission plane on the same side (psi = 0) with i <= e, S = 1 exactly.
    g0 = np.abs(np.arccos(mu0) - np.arccos(mu))
    _, _, s0 = ph._rough_cosines(mu0, mu, g0, math.radians(30))
    np.testing.assert_allclose(s0[mu0 >= mu], 1.0, atol=1e-6)
    assert np.all(ph.hapke([0.0, -0.5, 0.5], [0.5, 0.5, 0.0], 1.0, 0.5) == 0.0)
    assert np.all(np.isfinite(ph.hapke([1.0, 1.0, 1e-9], [1.0, 1e-9, 1.0], [0.0, 1.5, 1.5], 0.5)))


def test_hapke_phase_functions_and_opposition():
    g = np.linspace(0, np.pi, 2001)
    for p in (ph.HapkeParams(xi=-0.25), ph.HapkeParams(b=0.3, c=0.6)):
        pg = ph._phase_function(np.cos(g), p)
        # normalised: (1/4pi) * integral over the sphere = 1; back-scattering: p(0) > p(pi)
        assert 0.5 * integrate.simpson(pg * np.sin(g), x=g) == pytest.approx(1.0, abs=1e-6)
        assert pg[0] > pg[-1]
    # B_SH adds B0 * p(0) to the single-scattering bracket at g = 0
    pa, pb = ph.HapkeParams(b0=0.0, theta_bar=0.0), ph.HapkeParams(b0=1.5, theta_bar=0.0)
    diff = ph.hapke(0.7, 0.4, 0.0, 0.3, pb) - ph.hapke(0.7, 0.4, 0.0, 0.3, pa)
    p0 = (1 - 0.25**2) / (1 - 0.25) ** 3
    assert diff == pytest.approx(0.3 / (4 * np.pi) * 0.7 / 1.1 * 1.5 * p0, rel=1e-12)


def test_hapke_energy_sanity():
    smooth = ph.HapkeParams(b0=0.0, theta_bar=0.0, xi=0.0)
    rough = ph.HapkeParams(b0=0.0, theta_bar=math.radians(25), xi=0.0)
    for mu0 in (1.0, 0.3):
        a_smooth = hemispherical_albedo_gl(lambda m0, m, g: ph.hapke(m0, m, g, 1.0, smooth), mu0)
        a_rough = hemispherical_albedo_gl(lambda m0, m, g: ph.hapke(m0, m, g, 1.0, rough), mu0)
        assert a_smooth == pytest.approx(1.0, abs=0.02)  # conservative scattering, H approx ~1 %
        assert 0.5 < a_rough < a_smooth  # shadowing only removes light


def test_hapke_defaults_are_mathilde():
    p = ph.HapkeParams()
    assert (p.b0, p.h, p.xi, p.b, p.c) == (3.18, 0.074, -0.25, None, None)
    assert p.theta_bar == pytest.approx(math.radians(19))
    assert ph.C_TYPE_SINGLE_SCATTERING_ALBEDO == 0.035
    assert math.pi * ph.hapke(1.0, 1.0, 0.0, 0.035) == pytest.approx(0.041, abs=0.003)  # normal reflectance


# ----------------------------------------------------------------------------- registry, helpers, errors
def test_make_law_registry_and_roundtrip():
    assert ph.LAWS == {"lambert", "lommel_seeliger", "mcewen", "hapke"}
    rng = np.random.default_rng(9)
    mu0, mu, g = random_geometry(rng, 100)
    for law, fn in [
        (ph.make_law("lambert"), lambda: ph.lambert(mu0, mu, g, 0.2)),
        (ph.make_law("lommel_seeliger"), lambda: ph.lommel_seeliger(mu0, mu, g, 0.2)),
        (ph.make_law("mcewen", alpha0=0.5, ls_weight=1), lambda: ph.mcewen(mu0, mu, g, 0.2, 0.5, 1.0)),
        (ph.make_law("hapke", h=0.05), lambda: ph.hapke(mu0, mu, g, 0.2, ph.HapkeParams(h=0.05))),
    ]:
        np.testing.assert_array_equal(law.radiance_factor(mu0, mu, g, 0.2), fn())
        assert ph.make_law(**law.to_dict()) == law
    d = ph.make_law("hapke", b=0.2, c=0.1).to_dict()
    assert d["name"] == "hapke" and d["b"] == 0.2 and d["c"] == 0.1


@pytest.mark.parametrize(
    "name, params, match",
    [
        ("lamber", {}, "unknown photometric law 'lamber'; expected one of hapke, lambert, lommel_seeliger, mcewen"),
        ("mcewen", {"alpha": 1.0}, "unknown parameter 'alpha' for photometric law 'mcewen'"),
        ("lambert", {"albedo": 0.1}, "unknown parameter 'albedo'"),
        ("mcewen", {"alpha0": 60}, r"mcewen.alpha0 must be in \(0, pi\]"),
        ("mcewen", {"ls_weight": -1}, "mcewen.ls_weight"),
        ("hapke", {"h": 0.0}, "hapke.h must be > 0"),
        ("hapke", {"theta_bar": 19}, "hapke.theta_bar"),
        ("hapke", {"xi": 1.0}, "hapke.xi"),
        ("hapke", {"b": 0.3}, "hapke.b and hapke.c must be given together"),
        ("hapke", {"b0": float("nan")}, "hapke.b0 must be finite"),
        ("hapke", {"b0": "big"}, "hapke.b0 must be a number"),
    ],
)
def test_make_law_errors(name, params, match):
    with pytest.raises(UserError, match=match):
        ph.make_law(name, **params)


def test_bad_albedo_errors():
    with pytest.raises(UserError, match="lambert: albedo must be >= 0"):
        ph.lambert(1.0, 1.0, 0.0, -0.1)
    with pytest.raises(UserError, match="hapke: albedo must be >= 0 and <= 1"):
        ph.hapke(1.0, 1.0, 0.0, 1.2)


def test_angles_from_vectors():
    n = np.array([[0.0, 0.0, 2.0]])
    s = np.array([[1.0, 0.0, 1.0]])
    v = np.array([[-1.0, 0.0, 1.0]])
    mu0, mu, g = ph.angles_from_vectors(n, s, v)
    np.testing.assert_allclose([mu0[0], mu[0], g[0]], [math.sqrt(0.5), math.sqrt(0.5), math.pi / 2], rtol=1e-15)
    mu0, mu, g = ph.angles_from_vectors([0, 0, 1], [0, 0, 1], [[0, 0, 1], [0, 1e-9, 1]])
    assert mu0.shape == (2,) and g[0] == 0.0 and g[1] == pytest.approx(1e-9, rel=1e-6)
    with pytest.raises(UserError, match="to_sun contains zero-length"):
        ph.angles_from_vectors(n, [0, 0, 0], v)
    with pytest.raises(UserError, match=r"normal must have shape \(N, 3\)"):
        ph.angles_from_vectors(np.ones((4, 2)), s, v)
