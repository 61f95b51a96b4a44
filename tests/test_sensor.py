"""Tests for renderlab.sensor: radiometry, noise statistics, clipping, seeding, validation."""

import dataclasses
import math

import numpy as np
import pytest
from scipy import stats

from renderlab.errors import UserError
from renderlab.sensor import (SensorOptions, expected_dn, expose, exposure_for_peak,
                              mean_electrons)

# Each statistical check allows a 4-sigma deviation of its estimator; the chi^2 bounds use the
# same two-sided false-alarm probability (6.3e-5). The seeds are fixed, so the tests are
# deterministic; the tolerances come from sampling theory, not from tuning.
Z = 4.0
ALPHA = 2 * stats.norm.sf(Z)


def test_electrons_at_known_radiance_match_hand_computation():
    # Defaults: D = 6.25 mm, f = 25 mm, p = 5.5 um, t = 0.25 ms, QE 0.5, lambda 600 nm, tau 0.9,
    # dark 20 e/s. Hand computation for L = 10 W m^-2 sr^-1:
    #   aperture area   pi/4 * (6.25e-3)^2                   = 3.0679616e-5 m^2
    #   pixel solid ang (5.5e-6 / 25e-3)^2                   = 4.84e-8 sr
    #   power           10 * 0.9 * 3.0679616e-5 * 4.84e-8    = 1.3364041e-11 W
    #   energy          * 2.5e-4 s                           = 3.3410102e-15 J
    #   photon energy   6.62607015e-34 * 299792458 / 600e-9  = 3.3107431e-19 J
    #   photons         3.3410102e-15 / 3.3107431e-19        = 10091.421
    #   electrons       10091.421 * 0.5 + 20 * 2.5e-4        = 5045.710 + 0.005 = 5045.715
    mu = mean_electrons(np.full((2, 3), 10.0), SensorOptions())
    assert mu.shape == (2, 3)
    np.testing.assert_allclose(mu, 5045.715, rtol=1e-7)


def _flat_stats_case(options, mean_e, shape=(400, 500), seed=1):
    k = options.electrons_per_radiance
    dark = options.dark_current_e_per_s * options.exposure_s
    radiance = np.full(shape, (mean_e - dark) / k)
    res = expose(radiance, options, np.random.default_rng(seed))
    return res, res.dn.astype(np.float64).ravel()


@pytest.mark.parametrize("options, mean_e", [
    (SensorOptions(), 5000.0),                                           # 10-bit, 20 e/DN
    (SensorOptions(gain_e_per_dn=1.0, bits=16, full_well_e=60000.0,
                   bias_dn=100.0, read_noise_e=5.0, dark_current_e_per_s=1e4),
     300.0),                                                              # 1 e/DN
])
def test_flat_field_mean_and_variance_follow_poisson_plus_read_noise(options, mean_e):
    res, dn = _flat_stats_case(options, mean_e)
    np.testing.assert_allclose(res.electrons_mean, mean_e, rtol=1e-12)
    g = options.gain_e_per_dn
    # Theory: e ~ Poisson(mu) + N(0, s_r^2); DN = round(bias + e/g). Rounding to integers adds
    # a uniform(-1/2, 1/2) error (Sheppard): exact in the mean and +1/12 in variance when the
    # noise spans several DN, which holds for every case here (sigma >= 2 DN).
    var_e = mean_e + options.read_noise_e ** 2
    sigma_dn = math.sqrt(var_e) / g
    assert sigma_dn >= 2.0
    mean_theory = options.bias_dn + mean_e / g
    var_theory = var_e / g ** 2 + 1.0 / 12.0
    n = dn.size
    assert abs(dn.mean() - mean_theory) < Z * math.sqrt(var_theory / n)
    # (n-1) s^2 / sigma^2 ~ chi^2(n-1) for Gaussian data; the excess kurtosis here (< 1/mu for
    # Poisson, 0 for the read noise) widens the spread of s^2 by well under 1 %.
    s2 = dn.var(ddof=1)
    lo = stats.chi2.ppf(ALPHA / 2, n - 1) / (n - 1) * var_theory
    hi = stats.chi2.ppf(1 - ALPHA / 2, n - 1) / (n - 1) * var_theory
    assert lo < s2 < hi
    assert not res.saturated.any()


def test_shot_noise_is_one_poisson_draw_of_the_total_mean():
    # Without read noise and with 1 e/DN, DN - bias is exactly Poisson(mu): an
    # "image + poisson(image)" bug would double the mean; a Gaussian would fail the
    # lattice/positivity and the third-cumulant check (Poisson: k3 = mu).
    opts = SensorOptions(gain_e_per_dn=1.0, bits=16, full_well_e=60000.0, bias_dn=0.0,
                         read_noise_e=0.0)
    mu = 4.0
    res, dn = _flat_stats_case(opts, mu, shape=(500, 500), seed=7)
    n = dn.size
    assert abs(dn.mean() - mu) < Z * math.sqrt(mu / n)
    # Third central moment: Poisson mu3 = mu. The sample estimator's variance is
    # (mu6 - mu3^2 - 6 mu4 mu2 + 9 mu2^3)/n = (mu + 18 mu^2 + 6 mu^3)/n for a Poisson law.
    k3 = np.mean((dn - dn.mean()) ** 3)
    assert abs(k3 - mu) < Z * math.sqrt((mu + 18 * mu ** 2 + 6 * mu ** 3) / n)
    # Goodness of fit to the Poisson pmf over the bins expected to hold > 20 counts
    # (df = number of kept bins: the dropped tails remove the sum constraint; conservative).
    counts = np.bincount(dn.astype(int))
    expected = n * stats.poisson.pmf(np.arange(counts.size), mu)
    keep = expected > 20
    chi2 = np.sum((counts[keep] - expected[keep]) ** 2 / expected[keep])
    assert chi2 < stats.chi2.ppf(1 - ALPHA, keep.sum())


def test_full_well_saturation():
    opts = SensorOptions()  # bias 16 + 20000 e / 20 e/DN = 1016 < 1023
    res = expose(np.full((50, 60), 1e4), opts, np.random.default_rng(0))
    assert res.dn.dtype == np.uint16
    assert np.all(res.dn == 1016)
    assert res.saturated.all()
    assert np.all(expected_dn(np.full((2, 2), 1e4), opts) == 1016.0)


def test_adc_clipping_high_and_low():
    opts = SensorOptions(gain_e_per_dn=10.0)  # full well would be 16 + 2000 DN > 1023
    res = expose(np.full((50, 60), 1e4), opts, np.random.default_rng(0))
    assert np.all(res.dn == 1023) and res.saturated.all()
    # Zero bias and no signal: read noise goes negative half the time -> clipped to 0.
    opts = SensorOptions(bias_dn=0.0, read_noise_e=40.0, dark_current_e_per_s=0.0)
    res = expose(np.zeros((100, 100)), opts, np.random.default_rng(0))
    assert res.dn.min() == 0 and res.dn.max() < 1023
    assert 0.4 < np.mean(res.dn == 0) < 0.8
    assert not res.saturated.any()
    assert SensorOptions(bits=12).adc_max == 4095


def test_same_seed_identical_different_seed_different():
    rng = np.random.default_rng(123)
    radiance = rng.uniform(0, 30, size=(64, 80))
    opts = SensorOptions(psf_sigma_px=0.7)
    a = expose(radiance, opts, np.random.default_rng(42)).dn
    b = expose(radiance, opts, np.random.default_rng(42)).dn
    c = expose(radiance, opts, np.random.default_rng(43)).dn
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)


def test_psf_conserves_flux_and_spreads_a_point():
    radiance = np.zeros((41, 41))
    radiance[20, 20] = 1000.0
    sharp = SensorOptions(dark_current_e_per_s=0.0)
    blurred = dataclasses.replace(sharp, psf_sigma_px=2.0)
    e0 = mean_electrons(radiance, sharp)
    e1 = mean_electrons(radiance, blurred)
    np.testing.assert_allclose(e1.sum(), e0.sum(), rtol=1e-12)
    assert e1.max() < 0.05 * e0.max()
    # second moment of the blurred point = sigma^2 per axis
    yy, xx = np.mgrid[:41, :41]
    var_x = np.sum(e1 * (xx - 20) ** 2) / e1.sum()
    np.testing.assert_allclose(var_x, 4.0, rtol=1e-3)


def test_expected_dn_matches_sample_mean_and_exposure_for_peak():
    opts = SensorOptions()
    rng = np.random.default_rng(5)
    radiance = rng.uniform(0, 20, size=(200, 200))
    t = exposure_for_peak(radiance, opts, fraction=0.8)
    opts_t = dataclasses.replace(opts, exposure_s=t)
    mu = mean_electrons(radiance, opts_t)
    np.testing.assert_allclose(np.percentile(mu, 99.9), 0.8 * opts.full_well_e, rtol=1e-9)
    # flat field check of expected_dn vs the mean of many noisy pixels
    flat = np.full((300, 300), 10.0)
    dn = expose(flat, opts_t, rng).dn.astype(float)
    exp = expected_dn(flat, opts_t)[0, 0]
    var = (mean_electrons(flat, opts_t)[0, 0] + opts.read_noise_e ** 2) / opts.gain_e_per_dn ** 2
    assert abs(dn.mean() - exp) < Z * math.sqrt((var + 1 / 12) / dn.size)
    with pytest.raises(UserError, match="dark"):
        exposure_for_peak(np.zeros((4, 4)), dataclasses.replace(opts, dark_current_e_per_s=0.0))


@pytest.mark.parametrize("field, value", [
    ("aperture_diameter_m", -1.0), ("focal_length_m", 0.0), ("pixel_pitch_m", float("nan")),
    ("exposure_s", 0.0), ("quantum_efficiency", 0.0), ("quantum_efficiency", 1.2),
    ("wavelength_m", -5e-7), ("optical_transmission", 1.5), ("dark_current_e_per_s", -1.0),
    ("read_noise_e", float("inf")), ("full_well_e", 0.0), ("gain_e_per_dn", 0.0),
    ("bias_dn", -1.0), ("bias_dn", 2000.0), ("bits", 0), ("bits", 17), ("bits", 10.5),
    ("bits", True), ("psf_sigma_px", -0.1), ("exposure_s", "1 ms"),
])
def test_bad_options_raise_user_error_naming_the_field(field, value):
    with pytest.raises(UserError, match=field):
        SensorOptions(**{field: value})


def test_bad_radiance_raises_user_error():
    opts, rng = SensorOptions(), np.random.default_rng(0)
    img = np.ones((8, 8))
    img[3, 3] = np.nan
    with pytest.raises(UserError, match="NaN"):
        expose(img, opts, rng)
    with pytest.raises(UserError, match="negative"):
        expose(np.full((2, 2), -1.0), opts, rng)
    with pytest.raises(UserError, match="2-D"):
        expose(np.ones((4, 4, 3)), opts, rng)
    with pytest.raises(UserError, match="NaN"):
        exposure_for_peak(img, opts)


def test_options_are_frozen_and_defaults_look_like_arrm_camera():
    opts = SensorOptions()
    with pytest.raises(dataclasses.FrozenInstanceError):
        opts.bits = 12
    assert opts.bits == 10 and opts.adc_max == 1023
    fov_deg = math.degrees(2 * math.atan(512 * opts.pixel_pitch_m / opts.focal_length_m))
    assert 10 < fov_deg < 15
    assert opts.bias_dn + opts.full_well_e / opts.gain_e_per_dn <= opts.adc_max
