r"""Correlation surface (Retina eq. 9) over every integer shift of the search area.

For a shift (Δs, Δl) the predicted image I_p (template, valid mask V) is laid over the image I_e at
pixel (s0 + x + Δs, l0 + y + Δl), and over the N pixels valid in both

.. math:: C = \frac{\frac1N\sum I_p I_e - \mu_p\mu_e}{\sqrt{(\mu_{p_2}-\mu_p^2)(\mu_{e_2}-\mu_e^2)}}   (9)

μ are the means and μ_2 the means of the squares over those N pixels (Lewis 1995). The printed eq. 9 lacks
the square root in the denominator; without it C is not a correlation coefficient (it is not bounded by 1
and depends on the image scale), so the root is taken. On fully valid windows C equals OpenCV's
``matchTemplate(..., TM_CCOEFF_NORMED)`` (a test pins it to 1e-6). "Valid" means: the template pixel is
covered by the maplet (shadowed pixels count: their zeros carry the shadow signal), the image pixel lies
inside the image and is not masked out (e.g. saturated).

:func:`correlation_surface` evaluates the six masked sums (N, Σp, Σp², Σe, Σe², Σpe) for every shift as
cross-correlations by FFT (Lewis 1995, the paper's ref. 19, "fast normalized cross-correlation"), after
removing the means (C is invariant to offsets; this keeps the sums well conditioned). When every image
pixel of the search window is usable, N, Σp and Σp² do not depend on the shift and only three
cross-correlations are needed; all of them go through one batched forward real FFT and one inverse,
pruned to the 2r + 1 lags, with numba kernels for the FFT inputs, the spectra products and eq. 9.
The FFT size is the next fast size at or above the search window (any size at or above it is exact).
:func:`correlation_surface_direct` is the direct numba loop (same numbers to ~1e-12) and
:func:`correlation_surface_numpy` the plain-numpy version (benchmark baseline).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def _surface(image, image_ok, tpl, valid, s0, l0, radius, min_count):
    H, W = image.shape
    h, w = tpl.shape
    n = 2 * radius + 1
    C = np.full((n, n), np.nan)
    cnt = np.zeros((n, n), np.int64)
    for a in range(n):
        dl = a - radius
        for b in range(n):
            ds = b - radius
            N = 0
            sp = 0.0
            se = 0.0
            spp = 0.0
            see = 0.0
            spe = 0.0
            for y in range(h):
                li = l0 + y + dl
                if li < 0 or li >= H:
                    continue
                for x in range(w):
                    if not valid[y, x]:
                        continue
                    si = s0 + x + ds
                    if si < 0 or si >= W or not image_ok[li, si]:
                        continue
                    p = tpl[y, x]
                    e = image[li, si]
                    N += 1
                    sp += p
                    se += e
                    spp += p * p
                    see += e * e
                    spe += p * e
            cnt[a, b] = N
            if N < min_count:
                continue
            mp, me = sp / N, se / N
            vp, ve = spp / N - mp * mp, see / N - me * me
            if vp <= 1e-300 or ve <= 1e-300:
                continue
            C[a, b] = (spe / N - mp * me) / math.sqrt(vp * ve)
    return C, cnt


def _prep(image, template, valid, image_valid):
    image = np.ascontiguousarray(image, dtype=np.float64)
    template = np.ascontiguousarray(template, dtype=np.float64)
    valid = np.ones(template.shape, bool) if valid is None else np.ascontiguousarray(valid, dtype=bool)
    image_ok = np.ones(image.shape, bool) if image_valid is None else np.ascontiguousarray(image_valid, dtype=bool)
    return image, template, valid, image_ok


def correlation_surface_direct(image, template, valid=None, s0: int = 0, l0: int = 0, radius: int = 8,
                               image_valid=None, min_count: int = 16):
    """Eq. 9 at every integer shift |Δs|, |Δl| ≤ radius (direct numba loop).

    Parameters
    ----------
    image : (H, W) array
        The camera image I_e (DN or radiance).
    template : (h, w) array
        Predicted image I_p; ``template[y, x]`` sits on image pixel (s0 + x, l0 + y) at zero shift.
    valid : (h, w) bool array, optional
        Template pixels to use (default: all).
    s0, l0 : int
        Image pixel of the template's top-left pixel at zero shift.
    radius : int
        Search distance, px.
    image_valid : (H, W) bool array, optional
        Image pixels to use (default: all).
    min_count : int
        Minimum number N of overlapping valid pixels; fewer gives NaN.

    Returns
    -------
    C : (2r+1, 2r+1) float64
        ``C[Δl + r, Δs + r]``; NaN where undefined (too few pixels, no contrast).
    count : (2r+1, 2r+1) int64
        N at each shift.
    """
    image, template, valid, image_ok = _prep(image, template, valid, image_valid)
    return _surface(image, image_ok, template, valid, int(s0), int(l0), int(radius), int(min_count))


@njit(cache=True)
def _fill_full(win, tpl, valid, stack):
    """FFT inputs of the fully valid case: stack[0] = V, stack[1] = (I_p − μ_p) V, stack[2] = I_e − μ_e,
    stack[3] = (I_e − μ_e)² (zero-padded); returns N, Σp, Σp² of the mean-removed template."""
    h, w = tpl.shape
    N = 0
    sp = 0.0
    for y in range(h):
        for x in range(w):
            if valid[y, x]:
                N += 1
                sp += tpl[y, x]
    mp = sp / N
    Sp = 0.0
    Spp = 0.0
    for y in range(h):
        for x in range(w):
            if valid[y, x]:
                p = tpl[y, x] - mp
                stack[0, y, x] = 1.0
                stack[1, y, x] = p
                Sp += p
                Spp += p * p
    Hr, Wr = win.shape
    se = 0.0
    for y in range(Hr):
        for x in range(Wr):
            se += win[y, x]
    me = se / (Hr * Wr)
    for y in range(Hr):
        for x in range(Wr):
            e = win[y, x] - me
            stack[2, y, x] = e
            stack[3, y, x] = e * e
    return float(N), Sp, Spp


@njit(cache=True)
def _products_full(f):
    """Spectra of the three cross-correlations: conj(F_V)·F_E, conj(F_P)·F_E, conj(F_V)·F_E²."""
    out = np.empty((3, f.shape[1], f.shape[2]), np.complex128)
    for y in range(f.shape[1]):
        for x in range(f.shape[2]):
            fv, fp, fe = f[0, y, x].conjugate(), f[1, y, x].conjugate(), f[2, y, x]
            out[0, y, x] = fv * fe
            out[1, y, x] = fp * fe
            out[2, y, x] = fv * f[3, y, x]
    return out


@njit(cache=True)
def _coefficient_full(Se, See, Spe, N, Sp, Spp, min_count):
    """Eq. 9 from the sums when N, Σp, Σp² are the same at every shift; (C, count)."""
    n = Se.shape[0]
    C = np.full((n, n), np.nan)
    cnt = np.full((n, n), np.int64(np.rint(N)))
    if cnt[0, 0] < max(min_count, 1):
        return C, cnt
    mp = Sp / N
    vp = Spp / N - mp * mp
    if not vp > 1e-12 * max(Spp / N, 1e-300):
        return C, cnt
    scale_e = -np.inf
    for a in range(n):
        for b in range(n):
            scale_e = max(scale_e, See[a, b] / N)
    for a in range(n):
        for b in range(n):
            me = Se[a, b] / N
            ve = See[a, b] / N - me * me
            if ve > 1e-12 * max(scale_e, 1e-300):
                C[a, b] = (Spe[a, b] / N - mp * me) / math.sqrt(vp * ve)
    return C, cnt


def correlation_surface(image, template, valid=None, s0: int = 0, l0: int = 0, radius: int = 8,
                        image_valid=None, min_count: int = 16):
    """Eq. 9 at every integer shift by FFT cross-correlations (module docstring); arguments and results as
    :func:`correlation_surface_direct`."""
    from scipy import fft

    image = np.asarray(image, dtype=np.float64)
    template = np.asarray(template, dtype=np.float64)
    valid = np.ones(template.shape, bool) if valid is None else np.asarray(valid, dtype=bool)
    H, W = image.shape
    h, w = template.shape
    r = int(radius)
    s0, l0 = int(s0), int(l0)
    Hr, Wr = h + 2 * r, w + 2 * r
    n = 2 * r + 1
    C = np.full((n, n), np.nan)
    # FFT size: any size ≥ the search window keeps the lags 0 … 2r free of wrap-around; the next size
    # pocketfft handles fast (98 → 100 for a 66-px template and ±16 px) is ~30 % faster
    shape = (fft.next_fast_len(Hr, real=True), fft.next_fast_len(Wr, real=True))
    ya, yb = max(0, l0 - r), min(H, l0 - r + Hr)
    xa, xb = max(0, s0 - r), min(W, s0 - r + Wr)
    if not (ya < yb and xa < xb) or not valid.any():
        return C, np.zeros((n, n), np.int64)
    ry, rx = ya - (l0 - r), xa - (s0 - r)
    win = image[ya:yb, xa:xb]
    ok_win = None if image_valid is None else np.asarray(image_valid, dtype=bool)[ya:yb, xa:xb]
    full = win.shape == (Hr, Wr) and (ok_win is None or ok_win.all())
    if full:
        # every image pixel of the window usable (the common case): N, Σp, Σp² do not depend on the shift,
        # three cross-correlations remain (one forward, one inverse batched real FFT); numba kernels make
        # the FFT inputs, the spectra products and eq. 9 from the sums
        stack = np.zeros((4,) + shape)
        Nf, Spf, Sppf = _fill_full(win, template, valid, stack)
        f = fft.rfft2(stack, workers=1, overwrite_x=True)
        g = _products_full(f)
        # inverse transform pruned to the 2r + 1 lags: columns' inverse FFT, then only n rows' real inverse
        g = fft.ifft(g, axis=-2, workers=1, overwrite_x=True)[:, :n]
        Se, Spe, See = fft.irfft(g, n=shape[1], axis=-1, workers=1)[:, :, :n]
        return _coefficient_full(Se, See, Spe, Nf, Spf, Sppf, int(min_count))
    else:
        # all six masked sums in one forward and one inverse batched real FFT
        v = valid.astype(np.float64)
        P = (template - template[valid].mean()) * v
        OK = np.zeros((Hr, Wr))
        OK[ry:ry + yb - ya, rx:rx + xb - xa] = 1.0 if ok_win is None else ok_win
        if not OK.any():
            return C, np.zeros((n, n), np.int64)
        E = np.zeros((Hr, Wr))
        E[ry:ry + yb - ya, rx:rx + xb - xa] = win
        E = (E - E[OK > 0].mean()) * OK
        stack = np.zeros((6,) + shape)
        stack[0, :h, :w], stack[1, :h, :w], stack[2, :h, :w] = v, P, P * P
        stack[3, :Hr, :Wr], stack[4, :Hr, :Wr], stack[5, :Hr, :Wr] = OK, E, E * E
        f = fft.rfft2(stack, workers=1, overwrite_x=True)
        fa, fb = np.conj(f[:3]), f[3:]
        prod = np.stack([fa[0] * fb[0], fa[1] * fb[0], fa[2] * fb[0], fa[0] * fb[1], fa[0] * fb[2], fa[1] * fb[1]])
        N, Sp, Spp, Se, See, Spe = fft.irfft2(prod, s=shape, workers=1, overwrite_x=True)[:, :n, :n]
    N = np.rint(N)
    cnt = N.astype(np.int64)
    ok = cnt >= max(int(min_count), 1)
    Nn = np.where(ok, N, 1.0)
    mp, me = Sp / Nn, Se / Nn
    vp, ve = Spp / Nn - mp * mp, See / Nn - me * me
    scale_p = (Spp / Nn).max() if ok.any() else 1.0
    scale_e = (See / Nn).max() if ok.any() else 1.0
    ok &= (vp > 1e-12 * max(scale_p, 1e-300)) & (ve > 1e-12 * max(scale_e, 1e-300))
    with np.errstate(invalid="ignore", divide="ignore"):
        C[ok] = ((Spe / Nn - mp * me) / np.sqrt(vp * ve))[ok]
    return C, cnt


def correlation_surface_numpy(image, template, valid=None, s0: int = 0, l0: int = 0, radius: int = 8,
                              image_valid=None, min_count: int = 16):
    """Plain-numpy eq. 9 (one vectorised window per shift); same results as :func:`correlation_surface`."""
    image, template, valid, image_ok = _prep(image, template, valid, image_valid)
    H, W = image.shape
    h, w = template.shape
    n = 2 * radius + 1
    C = np.full((n, n), np.nan)
    cnt = np.zeros((n, n), np.int64)
    pad = radius + max(h, w)
    big = np.zeros((H + 2 * pad, W + 2 * pad))
    big[pad:pad + H, pad:pad + W] = image
    ok = np.zeros(big.shape, bool)
    ok[pad:pad + H, pad:pad + W] = image_ok
    for a in range(n):
        for b in range(n):
            ys, xs = pad + l0 + a - radius, pad + s0 + b - radius
            if ys < 0 or xs < 0 or ys + h > big.shape[0] or xs + w > big.shape[1]:
                continue
            m = valid & ok[ys:ys + h, xs:xs + w]
            N = int(m.sum())
            cnt[a, b] = N
            if N < min_count:
                continue
            p = template[m]
            e = big[ys:ys + h, xs:xs + w][m]
            mp, me = p.mean(), e.mean()
            vp, ve = (p * p).mean() - mp * mp, (e * e).mean() - me * me
            if vp > 1e-300 and ve > 1e-300:
                C[a, b] = ((p * e).mean() - mp * me) / math.sqrt(vp * ve)
    return C, cnt
