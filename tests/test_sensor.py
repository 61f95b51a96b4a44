"""Tests for renderlab.sensor.model: radiometry, noise statistics, clipping, seeding, validation."""

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from renderlab.errors import UserError
from renderlab.sensor import model as sensor
from renderlab.sensor.model import SensorOptions, expected_dn, expose, exposure_for_peak, mean_electrons

REPO = Path(__file__).resolve().parents[1]

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


@pytest.mark.parametrize("stream", ["per_pixel", "sequential"])
@pytest.mark.parametrize("options, mean_e", [
    (SensorOptions(), 5000.0),                                           # 10-bit, 20 e/DN
    (SensorOptions(gain_e_per_dn=1.0, bits=16, full_well_e=60000.0,
                   bias_dn=100.0, read_noise_e=5.0, dark_current_e_per_s=1e4),
     300.0),                                                              # 1 e/DN
])
def test_flat_field_mean_and_variance_follow_poisson_plus_read_noise(options, mean_e, stream):
    options = dataclasses.replace(options, noise_stream=stream)
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


@pytest.mark.parametrize("stream", ["per_pixel", "sequential"])
def test_shot_noise_is_one_poisson_draw_of_the_total_mean(stream):
    # Without read noise and with 1 e/DN, DN - bias is exactly Poisson(mu): an
    # "image + poisson(image)" bug would double the mean; a Gaussian would fail the
    # lattice/positivity and the third-cumulant check (Poisson: k3 = mu).
    opts = SensorOptions(gain_e_per_dn=1.0, bits=16, full_well_e=60000.0, bias_dn=0.0,
                         read_noise_e=0.0, noise_stream=stream)
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


@pytest.mark.parametrize("stream", ["per_pixel", "sequential"])
def test_same_seed_identical_different_seed_different(stream):
    rng = np.random.default_rng(123)
    radiance = rng.uniform(0, 30, size=(64, 80))
    opts = SensorOptions(psf_sigma_px=0.7, noise_stream=stream)
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
    # f/4 with 5.5 um pixels; the sensor has no focal length of its own (the camera's fx, fy is it)
    assert opts.focal_length_m is None and opts.aperture_diameter_m is None and opts.effective_f_number == 4.0
    assert opts.bias_dn + opts.full_well_e / opts.gain_e_per_dn <= opts.adc_max


# ------------------------------------------------------------------ one focal length: the camera's
def test_default_etendue_is_bit_identical_to_the_former_25mm_f4_lens():
    # the former defaults D = 6.25 mm, f = 25 mm: exposures and DN of every existing scene stay bit for bit
    legacy = SensorOptions(aperture_diameter_m=6.25e-3, focal_length_m=25.0e-3)
    assert SensorOptions().etendue_m2_sr == legacy.etendue_m2_sr
    assert SensorOptions(f_number=4.0).electrons_per_radiance == legacy.electrons_per_radiance
    assert legacy.effective_f_number == 4.0


@pytest.mark.parametrize("n, p", [(2.8, 5.5e-6), (1.4, 3.45e-6), (11.0, 12e-6)])
def test_etendue_depends_on_f_number_and_pixel_only(n, p):
    # (pi/4) D^2 * Omega with D = f/N and Omega = (p/f)^2 = 1/(fx fy): the focal length cancels
    opts = SensorOptions(f_number=n, pixel_pitch_m=p)
    np.testing.assert_allclose(opts.etendue_m2_sr, math.pi / 4 * (p / n) ** 2, rtol=1e-14)
    for f in (1.4e-3, 25e-3, 0.5):  # any lens with that f-number: same etendue
        np.testing.assert_allclose(SensorOptions(aperture_diameter_m=f / n, focal_length_m=f,
                                                 pixel_pitch_m=p).etendue_m2_sr, opts.etendue_m2_sr, rtol=1e-14)


def test_pixel_solid_angle_from_the_camera_pixel_map():
    assert sensor.pixel_solid_angle_sr(262.0, 258.0) == 1.0 / (262.0 * 258.0)
    np.testing.assert_allclose(sensor.pixel_solid_angle_sr(900.0, 870.0, 2.0, 0.7), 1 / (900 * 870 - 1.4),
                               rtol=1e-15)
    with pytest.raises(UserError, match="singular"):
        sensor.pixel_solid_angle_sr(10.0, 10.0, 10.0, 10.0)
    with pytest.raises(UserError, match="camera.fx"):
        sensor.pixel_solid_angle_sr(float("nan"), 10.0)


def test_optics_given_twice_must_agree():
    with pytest.raises(UserError, match="sensor.f_number = 2.8 disagrees with sensor.focal_length_m") as info:
        SensorOptions(aperture_diameter_m=6.25e-3, focal_length_m=25e-3, f_number=2.8)
    assert "\n" not in str(info.value)
    SensorOptions(aperture_diameter_m=6.25e-3, focal_length_m=25e-3, f_number=4.0)  # consistent: fine
    with pytest.raises(UserError, match="sensor.aperture_diameter_m needs a focal length"):
        SensorOptions(aperture_diameter_m=6.25e-3)


CAMERA_262 = {"fx": 262.0, "fy": 258.0}  # the demo's analytic scene


def test_scenario_sensor_focal_length_must_match_the_camera():
    from renderlab.scenario.camera import resolve_optics

    # the former defaults 25 mm / 5.5 um = 4545 px against the demo camera's 262 x 258 px: refused, both named
    with pytest.raises(UserError) as info:
        resolve_optics({"focal_length_m": 25e-3, "pixel_pitch_m": 5.5e-6}, **CAMERA_262)
    msg = str(info.value)
    assert "\n" not in msg and "4545.45 px" in msg and "259.992 px" in msg and "sensor.focal_length_m" in msg
    # consistent (within 0.1 %): accepted, and dropped -- the camera's focal length is the one used
    f_cam = 5.5e-6 * math.sqrt(262.0 * 258.0)
    out = resolve_optics({"focal_length_m": f_cam * 1.0005, "pixel_pitch_m": 5.5e-6, "bits": 12}, **CAMERA_262)
    assert out == {"pixel_pitch_m": 5.5e-6, "bits": 12}
    assert resolve_optics({"bits": 12}, **CAMERA_262) == {"bits": 12}  # nothing to tie: unchanged


def test_scenario_aperture_diameter_becomes_f_number_with_the_camera_focal_length():
    from renderlab.scenario.camera import resolve_optics

    D, p = 0.36e-3, 5.5e-6
    out = resolve_optics({"aperture_diameter_m": D, "pixel_pitch_m": p}, **CAMERA_262)
    assert set(out) == {"pixel_pitch_m", "f_number"}
    opts = SensorOptions(**out)
    # etendue = aperture area x the camera's pixel solid angle
    np.testing.assert_allclose(opts.etendue_m2_sr, math.pi / 4 * D ** 2 / (262.0 * 258.0), rtol=1e-13)
    with pytest.raises(UserError, match="sensor.f_number = 2 disagrees") as info:
        resolve_optics({"aperture_diameter_m": D, "f_number": 2.0}, **CAMERA_262)
    assert "f/3.97" in str(info.value)


def test_load_scenario_refuses_an_inconsistent_sensor_focal_length(tmp_path):
    from renderlab.scenario import load_scenario

    text = (REPO / "scenes" / "analytic_sphere_box.toml").read_text()
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace("[sensor]\n", "[sensor]\nfocal_length_m = 25e-3\npixel_pitch_m = 5.5e-6\n", 1))
    with pytest.raises(UserError, match=r"^bad.toml: sensor.focal_length_m / sensor.pixel_pitch_m"):
        load_scenario(bad)
    good = tmp_path / "good.toml"
    good.write_text(text.replace("[sensor]\n", "[sensor]\naperture_diameter_m = 0.36e-3\n", 1))
    sc, _ = load_scenario(good)
    assert set(sc.sensor.options_dict()) == {"f_number"}
    np.testing.assert_allclose(SensorOptions(**sc.sensor.options_dict()).etendue_m2_sr,
                               math.pi / 4 * 0.36e-3 ** 2 / (sc.camera.fx * sc.camera.fy), rtol=1e-13)
    # an existing scene's sensor section (no optics keys) is not touched: same manifest, same truth-cache key
    plain, _ = load_scenario(REPO / "scenes" / "analytic_sphere_box.toml")
    assert plain.to_dict()["sensor"] == {"auto_exposure": True, "auto_exposure_fraction": 0.8}
