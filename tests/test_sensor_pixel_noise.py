"""Per-pixel counter-based sensor noise (renderlab.sensor.noise): locality, the generator against published
test vectors and numpy's own Philox, the Poisson and Normal samplers against scipy, seeding, and the former
sequential stream kept bit for bit."""

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from renderlab.errors import UserError
from renderlab.sensor.model import SensorOptions, expose, mean_electrons
from renderlab.sensor.noise import frame_key, per_pixel_electrons, philox4x64

REPO = Path(__file__).resolve().parents[1]
M64 = 2 ** 64 - 1

# As in test_sensor.py: each check allows a 4-sigma deviation of its estimator (two-sided false-alarm
# probability 6.3e-5) and the chi^2 bounds use that probability; the seeds are fixed, so the tests are
# deterministic, and the tolerances come from sampling theory, not from tuning.
Z = 4.0
ALPHA = 2 * stats.norm.sf(Z)

# 1 e/DN, 16 bits, no dark current: a radiance pixel at 0 has mean 0 exactly
LINEAR = SensorOptions(gain_e_per_dn=1.0, bits=16, full_well_e=60000.0, bias_dn=100.0, read_noise_e=5.0,
                       dark_current_e_per_s=0.0)


# ------------------------------------------------------------------------------------ (1) locality
def _scene(rng, shape=(48, 64)):
    k = LINEAR.electrons_per_radiance
    radiance = rng.uniform(0.0, 3000.0, size=shape) / k  # means 0..3000 e: inversion and PTRS pixels
    radiance[rng.random(shape) < 0.3] = 0.0              # and dark pixels (mean exactly 0)
    return radiance


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_one_changed_radiance_pixel_changes_only_that_dn(seed):
    rng = np.random.default_rng(100 + seed)
    radiance = _scene(rng)
    dark = np.argwhere(radiance == 0.0)
    r, c = dark[len(dark) // 3]                       # a dark pixel in the first half of the image ...
    bumped = radiance.copy()
    bumped[r, c] = 2000.0 / LINEAR.electrons_per_radiance  # ... lit at 2000 e
    per_pixel = LINEAR
    a = expose(radiance, per_pixel, np.random.default_rng(seed)).dn
    b = expose(bumped, per_pixel, np.random.default_rng(seed)).dn
    changed = np.argwhere(a != b)
    assert changed.tolist() == [[r, c]]               # the lit pixel (2000 e vs ~0) and nothing else
    # The former single stream: numpy's Poisson draws nothing for a zero mean and two uniforms or more
    # otherwise, so the later pixels' draws shift (until a rejection happens to realign the stream):
    # the check above fails there.
    seq = dataclasses.replace(LINEAR, noise_stream="sequential")
    a = expose(radiance, seq, np.random.default_rng(seed)).dn
    b = expose(bumped, seq, np.random.default_rng(seed)).dn
    changed = np.argwhere(a != b)
    assert changed[0].tolist() == [r, c] and len(changed) > 10


def test_many_changed_pixels_and_a_psf_change_only_their_own_dn():
    rng = np.random.default_rng(7)
    radiance = _scene(rng)
    bumped = radiance.copy()
    idx = rng.choice(radiance.size, 40, replace=False)
    bumped.flat[idx] = bumped.flat[idx] * 1.5 + 100.0 / LINEAR.electrons_per_radiance
    a = expose(radiance, LINEAR, np.random.default_rng(3)).dn
    b = expose(bumped, LINEAR, np.random.default_rng(3)).dn
    assert set(np.flatnonzero(a != b)) <= set(idx.tolist())
    assert np.count_nonzero(a != b) > 20              # most of the 40 (mean +100 e or more) did change
    # With a PSF a pixel's mean changes wherever the blur spreads the change: DN change there only.
    blurred = dataclasses.replace(LINEAR, psf_sigma_px=1.0)
    mu_a, mu_b = mean_electrons(radiance, blurred), mean_electrons(bumped, blurred)
    a = expose(radiance, blurred, np.random.default_rng(3)).dn
    b = expose(bumped, blurred, np.random.default_rng(3)).dn
    assert np.all(mu_a[a != b] != mu_b[a != b])
    assert np.count_nonzero(mu_a == mu_b) > 100      # the blur leaves room for unchanged pixels


# ------------------------------------------------------------------------------------ (3) the generator
# Random123 known-answer vectors for philox4x64_10 (kat_vectors: counter words, key words -> output words).
KAT = [
    ((0, 0, 0, 0), (0, 0), (0x16554d9eca36314c, 0xdb20fe9d672d0fdc, 0xd7e772cee186176b, 0x7e68b68aec7ba23b)),
    ((M64, M64, M64, M64), (M64, M64),
     (0x87b092c3013fe90b, 0x438c3c67be8d0224, 0x9cc7d7c69cd777b6, 0xa09caebf594f0ba0)),
    ((0x243f6a8885a308d3, 0x13198a2e03707344, 0xa4093822299f31d0, 0x082efa98ec4e6c89),
     (0x452821e638d01377, 0xbe5466cf34e90c6c),
     (0xa528f45403e61d95, 0x38c72dbd566e9788, 0xa5a1610e72fd18b5, 0x57bd43b5e52b7fe6)),
]


@pytest.mark.parametrize("counter, key, expected", KAT)
def test_philox_matches_random123_known_answers(counter, key, expected):
    out = philox4x64(np.array([counter], dtype=np.uint64), np.array(key, dtype=np.uint64))
    assert [int(w) for w in out[0]] == list(expected)


def _words(c: int) -> np.ndarray:
    return np.array([(c >> (64 * j)) & M64 for j in range(4)], dtype=np.uint64)


def test_philox_matches_numpy_philox_bit_generator():
    # numpy's Philox (an independent C implementation) increments its 256-bit counter, then outputs the
    # block: started at c - 1 it returns the blocks of c, c + 1, ... as consecutive groups of 4 words.
    rng = np.random.default_rng(11)
    for _ in range(5):
        key = rng.integers(0, 2 ** 64, size=2, dtype=np.uint64)
        c = int.from_bytes(rng.bytes(32), "little") | (int(rng.integers(0, 2)) * M64)  # word 0 all ones: carries
        bits = np.random.Philox(counter=_words((c - 1) % 2 ** 256), key=key)
        expected = bits.random_raw(4 * 300).reshape(300, 4)
        counters = np.stack([_words((c + j) % 2 ** 256) for j in range(300)])
        np.testing.assert_array_equal(philox4x64(counters, key), expected)


def test_pixel_draws_are_philox_blocks_of_pixel_index_box_muller_and_inversion():
    """Draws 0-3 of pixel i are numpy-Philox block (i, 0, 0, 0); the read noise is Box-Muller of draws 0, 1;
    a mean below 10 is scipy's Poisson quantile of draw 2."""
    key = np.array([0x0123456789ABCDEF, 0xFEDCBA9876543210], dtype=np.uint64)
    shape = (40, 50)
    words = np.random.Philox(counter=_words(2 ** 256 - 1), key=key).random_raw(4 * 2000).reshape(2000, 4)
    u = ((words >> np.uint64(11)).astype(np.float64) + 0.5) * 2.0 ** -53
    assert u.min() > 0.0 and u.max() < 1.0
    for mu in (0.3, 4.0, 9.9):
        shot = per_pixel_electrons(np.full(shape, mu), 0.0, key).ravel()
        np.testing.assert_array_equal(shot, stats.poisson.ppf(u[:, 2], mu))
        both = per_pixel_electrons(np.full(shape, mu), 1.0, key).ravel()
        z = np.sqrt(-2.0 * np.log(u[:, 0])) * np.cos(2.0 * np.pi * u[:, 1])
        np.testing.assert_allclose(both - shot, z, rtol=0, atol=1e-12)


# ------------------------------------------------------------------------------------ (2) the samplers
def _chi2_against_scipy(k: np.ndarray, mu: float):
    """Pearson chi^2 of the draws against Poisson(mu) (scipy) and its degrees of freedom, on integer bins
    (single values or quantile bins) merged to >= 40 expected counts; for mu >= 1e12 against the normal
    law (|Poisson cdf - normal cdf| < 1/sqrt(mu) <= 1e-6, far below the sampling error of the bins), as
    scipy's Poisson cdf loses digits there (at 1e15 its quantiles and cdf disagree by 5e-4)."""
    n = k.size
    q = np.linspace(0.0, 1.0, 41)[1:-1]
    if mu >= 1e12:
        edges = mu + math.sqrt(mu) * stats.norm.ppf(q)
        cdf = stats.norm.cdf((edges - mu) / math.sqrt(mu))
    else:
        lo, hi = stats.poisson.ppf([1e-4, 1 - 1e-4], mu)
        edges = np.arange(lo + 1, hi + 1) if hi - lo < 60 else np.unique(stats.poisson.ppf(q, mu))
        edges = edges[edges > 0]                      # bins (-inf, e0 - 1], [e0, e1 - 1], ..., [e_last, inf)
        cdf = stats.poisson.cdf(edges - 1, mu)
    counts = np.bincount(np.searchsorted(edges, k, side="right"), minlength=edges.size + 1)
    p = np.diff(np.concatenate([[0.0], cdf, [1.0]]))
    expected, observed = [0.0], [0]
    for pj, cj in zip(p, counts):                     # merge neighbouring bins up to >= 40 expected counts
        if expected[-1] >= 40:
            expected.append(0.0)
            observed.append(0)
        expected[-1] += n * pj
        observed[-1] += cj
    if expected[-1] < 40:
        expected[-2:], observed[-2:] = [sum(expected[-2:])], [sum(observed[-2:])]
    expected, observed = np.array(expected), np.array(observed)
    assert expected.size >= 3
    chi2 = float(np.sum((observed - expected) ** 2 / expected))
    return chi2, expected.size - 1


MEANS = [0.3, 4.0, 9.9, 10.1, 37.0, 1e4, 1e7, 1e12, 1e15]


@pytest.mark.parametrize("j, mu", list(enumerate(MEANS)))
def test_poisson_sampler_matches_scipy(j, mu):
    n = 1_000_000
    key = np.array([j, 0xC0FFEE], dtype=np.uint64)
    k = per_pixel_electrons(np.full(n, mu), 0.0, key)
    assert np.all(k == np.floor(k)) and k.min() >= 0
    chi2, df = _chi2_against_scipy(k, mu)
    assert chi2 < stats.chi2.ppf(1 - ALPHA, df), (chi2, df)
    d = k - mu                                        # exact in float64 up to mu = 1e15
    assert abs(d.mean()) < Z * math.sqrt(mu / n)
    # Var(s^2) = (mu4 - sigma^4)/n + O(1/n^2), with mu4 = mu + 3 mu^2 for a Poisson law
    assert abs(d.var(ddof=1) - mu) < Z * math.sqrt((mu + 2 * mu * mu) / n)


def test_read_noise_is_standard_normal_and_independent_of_the_shot_noise():
    n = 400_000
    key = np.array([99, 1], dtype=np.uint64)
    for mu in (4.0, 500.0):                           # inversion and PTRS pixels
        shot = per_pixel_electrons(np.full(n, mu), 0.0, key)
        z = per_pixel_electrons(np.full(n, mu), 1.0, key) - shot  # read-noise draws do not move the shot draws
        assert stats.kstest(z, "norm").pvalue > ALPHA
        r = np.corrcoef(z, shot)[0, 1]
        assert abs(r) < Z / math.sqrt(n)


# ------------------------------------------------------------------------------------ (4) seeding
def test_same_seed_same_dn_and_the_documented_frame_key():
    rng = np.random.default_rng(5)
    radiance = _scene(rng)
    opts = dataclasses.replace(LINEAR, psf_sigma_px=0.6)
    a = expose(radiance, opts, np.random.default_rng(42)).dn
    assert np.array_equal(a, expose(radiance, opts, np.random.default_rng(42)).dn)
    assert np.array_equal(a, expose(radiance, opts, 42).dn)
    ss = np.random.SeedSequence(42)
    assert np.array_equal(a, expose(radiance, opts, ss).dn)
    assert not np.array_equal(a, expose(radiance, opts, np.random.default_rng(43)).dn)
    # frame key = two full-range uint64 draws of the generator; then the DN formula of the module docstring
    key = np.random.default_rng(42).integers(0, 2 ** 64, size=2, dtype=np.uint64)
    assert np.array_equal(frame_key(np.random.default_rng(42)), key)
    e = per_pixel_electrons(mean_electrons(radiance, opts), opts.read_noise_e, key)
    dn = np.clip(np.rint(opts.bias_dn + np.minimum(e, opts.full_well_e) / opts.gain_e_per_dn), 0, opts.adc_max)
    np.testing.assert_array_equal(a, dn.astype(np.uint16))
    with pytest.raises(TypeError, match="rng"):
        expose(radiance, opts, "42")


def test_sequential_stream_is_the_former_draw_order_bit_for_bit():
    rng = np.random.default_rng(8)
    radiance = _scene(rng)
    opts = SensorOptions(noise_stream="sequential", psf_sigma_px=0.8)
    got = expose(radiance, opts, np.random.default_rng(17))
    # the sensor's former code, step for step
    g = np.random.default_rng(17)
    mu = mean_electrons(radiance, opts)
    e = g.poisson(np.minimum(mu, 1e15)).astype(np.float64)
    e += g.normal(0.0, opts.read_noise_e, size=mu.shape)
    full = e >= opts.full_well_e
    dn = np.clip(np.rint(opts.bias_dn + np.minimum(e, opts.full_well_e) / opts.gain_e_per_dn), 0, opts.adc_max)
    np.testing.assert_array_equal(got.dn, dn.astype(np.uint16))
    np.testing.assert_array_equal(got.saturated, full | (dn >= opts.adc_max))


# ------------------------------------------------------------------------------------ the option
def test_noise_stream_option_and_scenario_key(tmp_path):
    from renderlab.scenario import load_scenario

    assert SensorOptions().noise_stream == "per_pixel"
    for bad in ("Per_Pixel", "", 1, None):
        with pytest.raises(UserError, match="sensor.noise_stream must be 'per_pixel' or 'sequential'"):
            SensorOptions(noise_stream=bad)
    text = (REPO / "scenes" / "analytic_sphere_box.toml").read_text()
    good = tmp_path / "good.toml"
    good.write_text(text.replace("[sensor]\n", '[sensor]\nnoise_stream = "sequential"\n', 1))
    sc, _ = load_scenario(good)
    assert SensorOptions(**sc.sensor.options_dict()).noise_stream == "sequential"
    for value in ('"random"', "3", "true"):
        bad = tmp_path / "bad.toml"
        bad.write_text(text.replace("[sensor]\n", f"[sensor]\nnoise_stream = {value}\n", 1))
        with pytest.raises(UserError) as info:
            load_scenario(bad)
        msg = str(info.value)
        assert "\n" not in msg and "sensor.noise_stream must be 'per_pixel' or 'sequential'" in msg


def test_parallel_kernel_does_not_depend_on_the_thread_count():
    """Pixels are drawn in parallel (numba prange): one thread and every thread give the same bytes."""
    import numba

    from renderlab.sensor.noise import per_pixel_electrons

    mu = np.random.default_rng(3).gamma(2.0, 40.0, (96, 80))
    mu[::7, ::5] = 3e5  # PTRS pixels beside inversion ones
    key = np.array([11, 12], np.uint64)
    n = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = per_pixel_electrons(mu, 5.0, key)
    finally:
        numba.set_num_threads(n)
    assert per_pixel_electrons(mu, 5.0, key).tobytes() == one.tobytes()
