r"""Sub-pixel peak finders for a correlation surface, and the pixel-locking curve.

Every finder takes the surface C and the index (row a, column b) of its integer maximum (not on the
border) and returns the sub-pixel offset (δs, δl) of the peak from that index, |δ| ≲ 1.

- ``retina_3x3`` — the paper's "linear interpolation over a 3×3 sub-pixel grid" (Wright et al., Peak
  Finding). The paper gives no formula; the lab reads it as: collapse the 3×3 neighbourhood onto each
  axis (row and column sums) and fit the symmetric *linear* (V-shaped) peak through the three values,
  δ = (c₊ − c₋) / (2 (c₀ − min(c₋, c₊))). A correlation peak of a texture with a broad spectrum is a cone,
  for which this linear fit is unbiased where the parabola is not.
- ``parabola_1d`` — a parabola through the centre row and column, δ = (c₋ − c₊) / (2 (c₋ − 2c₀ + c₊)).
- ``quadric_2d`` — least-squares quadric a + bx + cy + dx² + exy + fy² on the 3×3 neighbourhood, its
  stationary point (SPC-style peak interpolation).
- ``gaussian`` — a parabola through the logarithms (a Gaussian peak), on the row and column.
- ``gaussian_2d`` — the lab's refined step: the least-squares quadric of ``quadric_2d`` fitted to log C on
  the 3×3 neighbourhood, i.e. a 2-D Gaussian with a full (rotated, anisotropic) covariance,
  C ≈ A exp(−½ (x − x₀)ᵀ Σ⁻¹ (x − x₀)); its stationary point is the peak. It is exact on any such
  Gaussian (the 1-D ``gaussian`` is exact only when Σ is axis-aligned), and an NCC surface of a smooth,
  well-sampled texture is close to one near its maximum. Falls back to ``quadric_2d`` where a value of the
  neighbourhood is ≤ 0 (no logarithm). Measured pixel locking and noise against the registration
  Cramér–Rao bound: ``benchmarks/bench_retina_peak_step.py``.
- ``upsampled`` — the 5×5 neighbourhood interpolated by a bicubic spline and maximised on a 1/``factor``
  px grid (an upsampled correlation surface).

:func:`pixel_locking_curve` measures each finder's bias against known fractional shifts of a
band-limited random texture (shifted exactly in the Fourier domain).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from estimators.landmarks.correlation import correlation_surface


def _three(C, a, b):
    return C[a - 1:a + 2, b - 1:b + 2]


def _v_fit(m, c0, p):
    lo = min(m, p)
    den = 2.0 * (c0 - lo)
    return 0.0 if den <= 0 else (p - m) / den


def retina_3x3(C, a, b):
    """The paper's 3×3 linear interpolation (module docstring) → (δs, δl)."""
    W = _three(C, a, b)
    cols, rows = W.sum(axis=0), W.sum(axis=1)
    return _v_fit(*cols), _v_fit(*rows)


def _par(m, c0, p):
    den = m - 2.0 * c0 + p
    return 0.0 if den >= 0 else 0.5 * (m - p) / den


def parabola_1d(C, a, b):
    """Parabola through the centre row (δs) and centre column (δl)."""
    return _par(C[a, b - 1], C[a, b], C[a, b + 1]), _par(C[a - 1, b], C[a, b], C[a + 1, b])


_X, _Y = np.meshgrid([-1.0, 0.0, 1.0], [-1.0, 0.0, 1.0])
_QA = np.column_stack([np.ones(9), _X.ravel(), _Y.ravel(), _X.ravel() ** 2, _X.ravel() * _Y.ravel(), _Y.ravel() ** 2])
_QPINV = np.linalg.pinv(_QA)


def _quadric_max(values):
    """Stationary point (δs, δl) of the least-squares quadric through a 3×3 block, None unless a maximum."""
    _, bx, cy, d, e, f = _QPINV @ values.ravel()
    Hm = np.array([[2 * d, e], [e, 2 * f]])
    if np.linalg.det(Hm) <= 0 or d >= 0:
        return None
    dx, dy = np.linalg.solve(Hm, [-bx, -cy])
    return float(dx), float(dy)


def quadric_2d(C, a, b):
    """Least-squares quadric on the 3×3 neighbourhood; its stationary point (falls back to 1-D parabolas)."""
    p = _quadric_max(_three(C, a, b))
    return parabola_1d(C, a, b) if p is None else p


def gaussian_2d(C, a, b):
    """2-D Gaussian (quadric on log C, full covariance) on the 3×3 neighbourhood (module docstring);
    falls back to :func:`quadric_2d` where a value is ≤ 0 or log C has no maximum."""
    W = _three(C, a, b)
    if not np.all(W > 0):
        return quadric_2d(C, a, b)
    p = _quadric_max(np.log(W))
    return quadric_2d(C, a, b) if p is None else p


def gaussian(C, a, b):
    """Parabola through log C on the centre row and column (values clipped to ≥ 1e-6)."""
    L = np.log(np.maximum(_three(C, a, b), 1e-6))
    return _par(L[1, 0], L[1, 1], L[1, 2]), _par(L[0, 1], L[1, 1], L[2, 1])


def upsampled(C, a, b, factor: int = 10):
    """Bicubic spline through the 5×5 neighbourhood (3×3 at the edge): maximum on a 1/factor px grid,
    then polished by Newton steps on the spline (so the answer is not quantised to the grid)."""
    from scipy.interpolate import RectBivariateSpline

    r = 2 if (a >= 2 and b >= 2 and a + 2 < C.shape[0] and b + 2 < C.shape[1]) else 1
    Wn = C[a - r:a + r + 1, b - r:b + r + 1]
    if not np.all(np.isfinite(Wn)):
        return parabola_1d(C, a, b)
    t = np.arange(-r, r + 1, dtype=float)
    k = min(3, 2 * r)
    spl = RectBivariateSpline(t, t, Wn, kx=k, ky=k)  # first axis: rows (y), second: columns (x)
    g = np.linspace(-1.0, 1.0, 2 * factor + 1)
    Z = spl(g, g)
    i, j = np.unravel_index(np.argmax(Z), Z.shape)
    y, x = float(g[i]), float(g[j])
    f = lambda yy, xx: float(spl(yy, xx)[0, 0])  # noqa: E731
    hd = 1e-3  # central differences: valid for the biquadratic 3×3 spline too (its 2nd derivatives are
    for _ in range(4):  # not available from the spline itself, dx must stay below the degree)
        gy, gx = (f(y + hd, x) - f(y - hd, x)) / (2 * hd), (f(y, x + hd) - f(y, x - hd)) / (2 * hd)
        f0 = f(y, x)
        hyy = (f(y + hd, x) - 2 * f0 + f(y - hd, x)) / hd ** 2
        hxx = (f(y, x + hd) - 2 * f0 + f(y, x - hd)) / hd ** 2
        hxy = (f(y + hd, x + hd) - f(y + hd, x - hd) - f(y - hd, x + hd) + f(y - hd, x - hd)) / (4 * hd * hd)
        Hm = np.array([[hxx, hxy], [hxy, hyy]])
        if np.linalg.det(Hm) <= 0 or hxx >= 0:
            break
        step = np.linalg.solve(Hm, [gx, gy])
        x, y = float(np.clip(x - step[0], -1, 1)), float(np.clip(y - step[1], -1, 1))
        if np.hypot(*step) < 1e-6:
            break
    return x, y


FINDERS = {"retina_3x3": retina_3x3, "parabola_1d": parabola_1d, "quadric_2d": quadric_2d,
           "gaussian": gaussian, "gaussian_2d": gaussian_2d, "upsampled": upsampled}


@dataclass(frozen=True)
class Peak:
    """A located peak: shift (Δs, Δl) in px relative to zero shift, the peak correlation and the flags."""

    ds: float
    dl: float
    score: float
    on_border: bool


def locate_peak(C: np.ndarray, method: str = "retina_3x3") -> Peak | None:
    """Integer maximum of C (NaN ignored) refined by ``method``; None if C is all NaN.

    The shift is relative to the surface centre (zero shift). A maximum on the border of the search
    area (or next to an undefined value) is returned unrefined with ``on_border=True``.
    """
    if method not in FINDERS:
        raise ValueError(f"unknown peak finder {method!r} (choose from {', '.join(FINDERS)})")
    finite = np.isfinite(C)
    if not finite.any():
        return None
    r = (C.shape[0] - 1) // 2
    a, b = divmod(int(np.argmax(np.where(finite, C, -np.inf))), C.shape[1])  # = nanargmax, without its copies
    score = float(C[a, b])
    border = a == 0 or b == 0 or a == C.shape[0] - 1 or b == C.shape[1] - 1
    if not border and not finite[a - 1:a + 2, b - 1:b + 2].all():
        border = True
    if border:
        return Peak(float(b - r), float(a - r), score, True)
    dx, dy = FINDERS[method](C, a, b)
    dx, dy = min(max(float(dx), -1.0), 1.0), min(max(float(dy), -1.0), 1.0)
    return Peak(b - r + dx, a - r + dy, score, False)


def shifted_texture(shape, shift_sl, sigma_px: float, rng: np.random.Generator, pad: int = 0):
    """A band-limited random texture and the same texture shifted by (δs, δl) (Fourier shift, exact).

    Returns ``(base, moved)``: ``moved(s, l) = base(s − δs, l − δl)``, so content at pixel p of ``base``
    appears at p + δ in ``moved``.
    """
    from scipy.ndimage import fourier_gaussian, fourier_shift

    H, W = shape
    f = np.fft.fft2(rng.normal(size=(H, W)))
    f = fourier_gaussian(f, sigma_px)
    base = np.fft.ifft2(f).real
    moved = np.fft.ifft2(fourier_shift(f, (shift_sl[1], shift_sl[0]))).real
    return base, moved


def pixel_locking_curve(fractions, methods=tuple(FINDERS), size: int = 96, tpl: int = 48, radius: int = 4,
                        sigma_px: float = 1.2, trials: int = 4, seed: int = 0):
    """Bias (mean estimated − true shift, px) of each finder vs a known fractional shift.

    The shift (f, f/2) is applied to a band-limited texture (σ = ``sigma_px``); a centred ``tpl``-px
    template cut from the unshifted texture is correlated (eq. 9) with the shifted one.

    Returns
    -------
    dict
        ``{method: (bias_s (F,), bias_l (F,))}`` for the fractions F.
    """
    rng = np.random.default_rng(seed)
    fr = np.asarray(fractions, float)
    out = {m: (np.zeros(len(fr)), np.zeros(len(fr))) for m in methods}
    s0 = (size - tpl) // 2
    for _ in range(trials):
        texture_seed = int(rng.integers(2**63))  # one texture per trial, the same for every fraction
        for k, f in enumerate(fr):
            base, moved = shifted_texture((size, size), (f, f / 2), sigma_px, np.random.default_rng(texture_seed))
            T = base[s0:s0 + tpl, s0:s0 + tpl]
            C, _ = correlation_surface(moved, T, None, s0, s0, radius)
            for m in methods:
                p = locate_peak(C, m)
                out[m][0][k] += (p.ds - f) / trials
                out[m][1][k] += (p.dl - f / 2) / trials
    return out
