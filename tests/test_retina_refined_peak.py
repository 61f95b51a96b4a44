"""The refined peak step of ``retina_refined`` (``gaussian_2d`` + 2 re-centred passes, estimators.retina.recentre)
against independent oracles: analytic rotated Gaussian surfaces, band-limited textures moved by scipy's Fourier
shift, Retina-rendered maplets seen from a camera translated by a known amount, and the registration Cramér–Rao
bound of renderlab.campaign.scoring. The paper's 3×3 step stays Retina's default."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.ndimage import fourier_shift

from estimators.landmarks.peaks import locate_peak, shifted_texture
from estimators.retina.peak_step import estimates, noise_sigma, texture_case
from estimators.retina.recentre import moved_template

Y, X = np.mgrid[-4:5, -4:5].astype(float)


@pytest.mark.parametrize("x0, y0, rho", [(0.31, -0.12, 0.6), (-0.47, 0.22, -0.4), (0.05, 0.44, 0.0)])
def test_gaussian_2d_is_exact_on_a_rotated_anisotropic_gaussian(x0, y0, rho):
    """A full-covariance Gaussian peak (correlation ρ between the axes): gaussian_2d recovers its centre to
    round-off; the 1-D Gaussian fit, which only sees the centre row and column, does not when ρ ≠ 0."""
    sx, sy = 1.3, 0.9
    dx, dy = X - x0, Y - y0
    q = (dx / sx) ** 2 - 2 * rho * dx * dy / (sx * sy) + (dy / sy) ** 2
    C = 0.9 * np.exp(-q / (2 * (1 - rho ** 2)))
    p = locate_peak(C, "gaussian_2d")
    assert abs(p.ds - x0) < 1e-9 and abs(p.dl - y0) < 1e-9, (p.ds, p.dl)
    if rho != 0:
        g = locate_peak(C, "gaussian")
        assert max(abs(g.ds - x0), abs(g.dl - y0)) > 0.02, "the oracle surface must separate the two fits"


def test_gaussian_2d_falls_back_to_the_quadric_without_logarithms():
    C = 1.0 - 0.3 * (X - 0.2) ** 2 - 0.2 * (Y + 0.1) ** 2  # negative around the 3x3: no log
    C[4, 3] = -0.1
    assert locate_peak(C, "gaussian_2d") == locate_peak(C, "quadric_2d")


def test_moved_template_matches_scipy_fourier_shift():
    """Cubic B-spline moving of a band-limited texture vs scipy.ndimage.fourier_shift (exact for it): < 2 % rms of
    the texture's std away from the edges (measured 0.6-1.3 %)."""
    rng = np.random.default_rng(3)
    base, _ = shifted_texture((64, 64), (0, 0), 1.2, rng)
    for ph in [(0.3, -0.4), (-0.5, 0.5), (0.0, 0.2)]:
        oracle = np.fft.ifft2(fourier_shift(np.fft.fft2(base), (ph[1], ph[0]))).real
        T, V = moved_template(base, np.ones(base.shape, bool), ph)
        err = (T - oracle)[8:-8, 8:-8]
        assert np.sqrt(np.mean(err ** 2)) < 0.02 * base.std(), ph
        assert not V[:, 0].any() and not V[-1].any() and V[1:-1, 1:-1].all()  # eroded by one pixel on every side


FRACTIONS = np.round(np.linspace(-0.45, 0.45, 7), 3)


def test_refined_step_is_unbiased_on_fourier_shifted_textures():
    """Known sub-pixel shifts (f, f/2) of band-limited textures (σ 1.2 px): the refined step's error on every
    single texture and shift stays under the issue's 0.02 px (measured ≤ 0.011), where the paper's 3×3 step's
    exceeds 0.04 px (measured 0.11)."""
    worst = {"gaussian_2d_rc": 0.0, "retina_3x3": 0.0}
    for seed in (11, 12):
        for f in FRACTIONS:
            c = texture_case(1.2, (f, f / 2), seed)
            e = estimates(c, steps=tuple(worst))
            for m in worst:
                worst[m] = max(worst[m], float(np.max(np.abs(np.subtract(e[m], c.shift)))))
    assert worst["gaussian_2d_rc"] < 0.02, worst
    assert worst["retina_3x3"] > 0.04, worst  # the oracle case is one where the steps differ


def test_refined_step_noise_is_near_the_registration_crlb():
    """SNR 20 on a texture: the spread of the refined step over 30 noise draws is within 1.5x the registration
    CRLB (measured about 1.05-1.1x; the CRLB from renderlab.campaign.scoring, independent code)."""
    from renderlab.campaign.scoring import registration_crlb

    c = texture_case(1.2, (0.27, -0.18), 21)
    rng = np.random.default_rng(5)
    est = np.array([estimates(c, steps=("gaussian_2d_rc",), snr=20.0, rng=rng)["gaussian_2d_rc"] for _ in range(30)])
    var = np.full(c.image.shape, np.inf)
    var[c.l0:c.l0 + 48, c.s0:c.s0 + 48] = noise_sigma(c, 20.0) ** 2
    bound = registration_crlb(c.image, var)
    ratio = np.std(est, axis=0, ddof=1) / np.asarray(bound)
    assert np.all(ratio < 1.5) and np.all(ratio > 0.6), ratio
    assert np.all(np.abs(est.mean(axis=0) - c.shift) < 0.02), est.mean(axis=0)  # measured 0.007 / 0.005 px


def test_refined_step_on_retina_rendered_maplets():
    """Retina re-renders its template from an a-priori camera translated by a known amount
    (estimators.retina.locking, the benchmark's three maplets and eleven shifts): the refined step's mean bias
    stays under the issue's 0.02 px (measured 0.017 / 0.015 px, s / l), the paper's 3×3 step's does not (0.060)."""
    from estimators.retina.locking import rendered_locking_curve

    fr = np.round(np.linspace(-0.5, 0.5, 11), 3)
    curve = rendered_locking_curve(fr, methods=("gaussian_2d_rc", "retina_3x3"))
    assert max(np.abs(b).max() for b in curve["gaussian_2d_rc"]) < 0.02, curve["gaussian_2d_rc"]
    assert max(np.abs(b).max() for b in curve["retina_3x3"]) > 0.02


def test_retina_keeps_the_paper_step_and_retina_refined_is_registered():
    from renderlab import plugins
    from renderlab.contracts.landmark import LandmarkMethodOptions

    paper = plugins.landmark_methods.get("retina")(LandmarkMethodOptions())
    refined = plugins.landmark_methods.get("retina_refined")(LandmarkMethodOptions())
    assert (paper.peak, paper.options.recentre_passes) == ("retina_3x3", 0)
    assert (refined.name, refined.peak, refined.options.recentre_passes) == ("retina_refined",
                                                                           "gaussian_2d+recentre2", 2)
