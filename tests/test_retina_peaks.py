"""Sub-pixel peak finders: exact on the analytic peak shape each one assumes, and the pixel-locking curve
(bias vs known fractional shift) on band-limited textures shifted exactly in the Fourier domain and on
Retina-rendered maplets moved by a known camera translation."""

from __future__ import annotations

import numpy as np
import pytest

from estimators.landmarks.peaks import FINDERS, locate_peak, pixel_locking_curve
from estimators.retina import CameraPoseEstimate, RetinaOptions, build_mesh, measure_landmark, project_point
from estimators.retina.predict import render_template
from renderlab.geometry.camera import CameraModel
from renderlab.geometry.maplet import Maplet

R = 5
Y, X = np.mgrid[-R:R + 1, -R:R + 1].astype(float)
PEAKS = [(0.0, 0.0), (0.31, -0.12), (-0.47, 0.22), (0.05, 0.44), (-0.2, -0.38)]


def _surface(kind, x0, y0):
    if kind == "parabola":
        return 1.0 - 0.04 * (X - x0) ** 2 - 0.07 * (Y - y0) ** 2
    if kind == "gauss":
        return np.exp(-((X - x0) ** 2 / (2 * 1.3 ** 2) + (Y - y0) ** 2 / (2 * 0.9 ** 2)))
    if kind == "cone":
        return (1.0 - 0.15 * np.abs(X - x0)) * (1.0 - 0.2 * np.abs(Y - y0))
    raise ValueError(kind)


# the surface family on which each finder is exact (to round-off), and on which it is only close
EXACT = {"parabola_1d": "parabola", "quadric_2d": "parabola", "gaussian": "gauss", "retina_3x3": "cone"}


@pytest.mark.parametrize("x0, y0", PEAKS)
@pytest.mark.parametrize("method", sorted(EXACT))
def test_finder_exact_on_its_model(method, x0, y0):
    p = locate_peak(_surface(EXACT[method], x0, y0), method)
    assert not p.on_border
    assert abs(p.ds - x0) < 1e-9 and abs(p.dl - y0) < 1e-9, (p.ds, p.dl)


@pytest.mark.parametrize("x0, y0", PEAKS)
def test_upsampled_finder_on_smooth_peak(x0, y0):
    """A well-sampled peak (Gaussian, σ = 1.5 px): the bicubic spline's interpolation error is small."""
    C = np.exp(-((X - x0) ** 2 + (Y - y0) ** 2) / (2 * 1.5 ** 2))
    p = locate_peak(C, "upsampled")
    assert abs(p.ds - x0) < 0.05 and abs(p.dl - y0) < 0.05, (p.ds, p.dl)  # measured ≤ 0.03 px


def test_border_peak_is_flagged():
    C = _surface("gauss", 4.8, 0.0)  # true maximum beyond the search area
    p = locate_peak(C, "quadric_2d")
    assert p.on_border and p.ds == R


FRACTIONS = np.round(np.linspace(-0.5, 0.5, 11), 3)


def test_pixel_locking_curve_textures():
    """Every finder recovers known fractional shifts of a band-limited texture (σ = 1.2 px) to 0.1 px; the
    bias vanishes at integer shifts and is odd in the shift. The table itself is printed by
    ``benchmarks/bench_retina_pixel_locking.py``."""
    curve = pixel_locking_curve(FRACTIONS, trials=3, seed=1)
    zero = int(np.flatnonzero(FRACTIONS == 0)[0])
    for m, (bs, bl) in curve.items():
        for b in (bs, bl):
            assert np.abs(b).max() < 0.1, (m, np.round(b, 3))
            assert abs(b[zero]) < 0.01, (m, b[zero])
        inner = slice(1, -1)  # ±0.5 px is ambiguous (two equal integer maxima)
        np.testing.assert_allclose(bs[inner], -bs[inner][::-1], atol=0.02, err_msg=m)


def _plain_maplet(n=41, seed=5):
    from scipy.ndimage import gaussian_filter

    rng = np.random.default_rng(seed)
    h = gaussian_filter(rng.normal(0, 0.6, (n, n)), 1.5)
    a = 1 + 0.3 * gaussian_filter(rng.normal(size=(n, n)), 1.0) / 0.28
    return Maplet(3, np.array([0.5, -0.2, 0.0]), np.eye(3), 0.1, h, np.clip(a, 0.3, 3))


@pytest.mark.parametrize("method", sorted(FINDERS))
def test_retina_rendered_maplet_subpixel_shift(method):
    """An image rendered by Retina's own ray tracer at the true pose; the a-priori camera is translated
    parallel to the image plane so the landmark's predicted pixel moves by a known fractional amount."""
    cam = CameraModel.from_dict({"width": 96, "height": 96, "fx": 110.0, "fy": 110.0, "cx": 47.5, "cy": 47.5})
    M = _plain_maplet()
    mesh = build_mesh(M)
    sun = np.array([0.5, 0.3, 0.8]) / np.linalg.norm([0.5, 0.3, 0.8])
    R = np.diag([1.0, -1.0, -1.0])  # looking straight down; camera +x = maplet +x, +y = maplet −y
    true = CameraPoseEstimate(R, np.array([0.5, -0.2, 10.0]))
    tpl = render_template(mesh, cam, true, sun)
    img = np.zeros((96, 96))
    img[tpl.l0:tpl.l0 + tpl.image.shape[0], tpl.s0:tpl.s0 + tpl.image.shape[1]] = tpl.image
    valid = np.zeros((96, 96), bool)
    valid[tpl.l0:tpl.l0 + tpl.image.shape[0], tpl.s0:tpl.s0 + tpl.image.shape[1]] = tpl.valid
    truth = project_point(cam, true, M.center_m)
    for dx, dy in [(0.023, -0.035), (-0.062, 0.016), (0.035, 0.07)]:
        ap = CameraPoseEstimate(R, true.position_m + np.array([dx, dy, 0.0]))
        r = measure_landmark(img, mesh, cam, ap, sun, 3, RetinaOptions(peak=method), image_valid=valid)
        assert r.has_result, r.flags
        err = np.hypot(r.meas_s - truth[0], r.meas_l - truth[1])
        shift = np.hypot(r.pred_s - truth[0], r.pred_l - truth[1])
        assert shift > 0.3, "the a-priori pose must move the prediction by a sub-pixel/pixel amount"
        print(method, round(err, 3), round(shift, 3))
        # 0.2 px: the finder's share of Retina's 0.3 px acceptance; the 1-D finders (row/column only) and the
        # linear 3x3 fit are biased on this smooth, anisotropic peak (measured 0.10-0.15 px), the 2-D ones not
        assert err < (0.05 if method in ("quadric_2d", "upsampled") else 0.2), (method, err, shift)


def test_upsampled_finder_on_a_small_search_area():
    """A ±2 px search (5×5 surface) with the maximum next to the border: the spline falls to the 3×3
    neighbourhood (biquadratic; no second derivatives from the spline itself), still near the true peak."""
    y, x = np.mgrid[-2:3, -2:3].astype(float)
    x0, y0 = -0.7, 1.2  # integer maximum at (Δs, Δl) = (−1, 1): a = 3, b = 1, r falls to 1
    C = np.exp(-((x - x0) ** 2 + (y - y0) ** 2) / 2.0)
    p = locate_peak(C, "upsampled")
    assert not p.on_border
    assert abs(p.ds - x0) < 0.1 and abs(p.dl - y0) < 0.1, (p.ds, p.dl)


def test_pixel_locking_curve_rendered_maplets():
    """The rendered-maplet pixel-locking curve (``estimators.retina.locking``; printed by
    ``benchmarks/bench_retina_pixel_locking.py``): every finder recovers known fractional shifts, unbiased
    at zero shift; the 2-D fits lock least (measured max |bias| 0.03 px), the linear 3×3 fit 0.06 px,
    the 1-D parabola and Gaussian, which only see the centre row and column of this anisotropic peak,
    lock most (0.11 px in line)."""
    from estimators.retina.locking import rendered_locking_curve

    curve = rendered_locking_curve(FRACTIONS)
    zero = int(np.flatnonzero(FRACTIONS == 0)[0])
    bound = {"quadric_2d": 0.05, "upsampled": 0.05, "retina_3x3": 0.1, "parabola_1d": 0.15, "gaussian": 0.15,
             "gaussian_2d": 0.02}  # the refined step: measured 0.011 / 0.012 px (s / l)
    for m, (bs, bl) in curve.items():
        for b in (bs, bl):
            assert abs(b[zero]) < 0.01, (m, b[zero])
            assert np.abs(b).max() < bound[m], (m, np.round(b, 3))
    # pixel locking, not noise: the 1-D parabola pulls the estimate toward the integer (bias against f)
    bl = curve["parabola_1d"][1]
    assert np.all(bl[1:zero] > 0.01) and np.all(bl[zero + 1:-1] < -0.01), np.round(bl, 3)
