r"""Maximum-likelihood sub-pixel shift: Gauss–Newton on the template itself, started from the correlation peak.

Description
-----------
Retina's peak step (Wright et al., "Peak Finding") and every finder of :mod:`estimators.landmarks.peaks` look only at the
integer-lag correlation surface C (eq. 9) around its maximum. This step goes back to the pixels. Under white
Gaussian pixel noise of variance σ², the image is modelled on the template's footprint as

.. math:: I_e(p) = a\,T(p - p_0 - \delta) + b + n(p), \qquad n \sim \mathcal N(0, \sigma^2)        (ML-1)

with T the noise-free prediction (Retina's synthetic image, eqs. 5–8, placed at p₀ = (s0, l0) by eqs. 1–4)
continued between pixels by its cubic B-spline interpolant, δ = (Δs, Δl) the shift, a a gain and b an offset
(eq. 9 is invariant to both; they absorb the unknown exposure and albedo scale). The maximum-likelihood δ
minimises

.. math:: \chi^2(\delta, a, b) = \sum_{p \in P} \big(I_e(p) - a\,T(p - p_0 - \delta) - b\big)^2            (ML-2)

over a fixed pixel set P (the footprint, eroded by ``erode_px``, placed at the starting integer shift, minus
image pixels that are masked or off the image). Outside the footprint the template is continued by its nearest
footprint pixel before the spline is fitted, so footprint pixels moved by up to a pixel read a smooth
continuation rather than a step to an arbitrary fill. Gauss–Newton (Lucas–Kanade with gain and offset) with the
Jacobian columns (−a ∂T/∂s, −a ∂T/∂l, T, 1), the spline's own exact derivatives, iterated from the peak
finder's estimate until the step is under ``tol_px``. Only the template is interpolated; the image is used at
its pixels, so its noise stays white and (ML-2) is the exact negative log-likelihood of (ML-1).

Why: the Fisher information of (ML-1) for θ = (δ, a, b) is

.. math:: \mathcal J = \sigma^{-2} \sum_{p\in P} h_p h_p^\mathsf T, \qquad
          h_p = (-a\,\partial_s T, -a\,\partial_l T, T, 1)(p - p_0 - \delta)                                (ML-3)

and the shift's Cramér–Rao bound is the δ block of 𝒥⁻¹ (the a, b nuisance removed by the Schur complement).
The ML estimator reaches it asymptotically (high SNR) when the model is right; a step that fits the 3 × 3
correlation values throws away the information of the template's sharp structure (shadow edges, small
craters) that C's neighbourhood does not resolve. When the prediction is not the image (re-rendered from a
wrong pose, photometric error) the mismatch is a bias, not noise. :func:`ml_shift` also returns the
linearised covariance σ̂² [𝒥σ²]⁻¹ (σ̂² from the residual), the estimator's own error bar; the residual holds the
model error too, so at high SNR it is conservative (measured on 48² textures at SNR 50: 1.4–2.8× the spread,
whose ratio to the exact-gradient CRLB is 0.97–1.05).

What remains (measured on the benchmark's 15 EV5 templates, prediction = image, SNR 20, 100 draws each): the
spread is 1.00× the bound of the model the step uses (ML-3 with the spline's derivatives), and that bound is
1.14× the Fisher bound of the rendered scene (:func:`~.peak_step.rendered_crlb`; 1.18× even for a 9 × 9-ray
template). The spline of a sampled template under-states how a sharp scene's pixels change with a sub-pixel
shift; only derivatives from the renderer itself (templates re-rendered at shifted poses) would close that gap.
The same limit sets the bias: ≤ 0.010 px on those templates, but ≈ 0.02 px on aliased texture (sub-pixel
detail that the sampled template, and so its spline, cannot represent); do not quote 0.01 px beyond
well-sampled scenes.

Tuning
------
:class:`MlShiftOptions`: ``iterations`` (Gauss–Newton steps, 10; it converges in 2–3 from a ``gaussian_2d``
start), ``tol_px`` (stop when the step is smaller, 1e-4 px), ``erode_px`` (footprint erosion, 0 px; 1–2 px keep
the spline's support on predicted pixels at the price of their information: measured on the benchmark's 15 EV5
templates, 25 draws, σ/CRLB at SNR 20 1.06 / 1.12 / 1.23 for 0 / 1 / 2 px, max |bias| 0.010 / 0.008 / 0.007 px
on those smooth, well-sampled templates; on aliased texture, detail finer than the pixels, the bias is ≈ 0.02 px
at 0 px erosion, because the spline of a sampled template mis-states such a scene between pixels),
``fill`` (``nearest``; ``mean`` fills with the footprint mean as :mod:`.recentre` does: 0.032 px bias at 0 px
erosion), ``max_move_px`` (farther than this from the start = no convergence, the start is kept, 1.5 px),
``min_pixels`` (fewer usable pixels = the start is kept).

Use
---
::

    from estimators.retina.ml_shift import ml_shift
    r = ml_shift(image, tpl.image, tpl.valid, tpl.s0, tpl.l0, peak.ds, peak.dl, image_valid)
    r.ds, r.dl, r.sigma_px, r.converged          # px; sigma_px: linearised 1σ of (Δs, Δl)

Or through Retina: ``RetinaOptions(peak="gaussian_2d", refine="ml_shift")`` (the lab's ``retina_ml`` method).

References
----------
C. A. Wright et al., "Relative Terrain Imaging Navigation (RETINA) Tool for the Asteroid Redirect Robotic Mission
(ARRM)", NASA GSFC, 2016 (eqs. 1–4 projection, 5–8 synthetic image, eq. 9 correlation and "Peak Finding", which
this step refines). B. D. Lucas, T. Kanade, "An iterative image registration technique with an application to
stereo vision", IJCAI 1981 (the Gauss–Newton registration). M. Unser, "Splines: a perfect fit for signal and
image processing", IEEE Signal Processing Magazine 16(6), 1999 (cubic B-spline interpolation and derivatives).
S. M. Kay, "Fundamentals of Statistical Signal Processing: Estimation Theory", Prentice Hall, 1993 (ch. 3, the
CRLB with nuisance parameters; ch. 7, asymptotic efficiency of the MLE).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class MlShiftOptions:
    """Gauss–Newton settings (module docstring, Tuning)."""

    iterations: int = 10
    tol_px: float = 1e-4
    erode_px: int = 0
    max_move_px: float = 1.5
    min_pixels: int = 16
    fill: str = "nearest"

    def __post_init__(self):
        if self.iterations < 1 or self.erode_px < 0 or not self.tol_px > 0 or not self.max_move_px > 0 \
                or self.min_pixels < 5 or self.fill not in ("nearest", "mean"):
            raise ValueError("MlShiftOptions: iterations >= 1, erode_px >= 0, tol_px > 0, max_move_px > 0, "
                             f"min_pixels >= 5 and fill 'nearest' or 'mean' required (got {self})")


@dataclass(frozen=True)
class MlShift:
    """Result of :func:`ml_shift`: the shift (px), gain a and offset b of (ML-1), the linearised 1σ of the shift
    (px), the residual RMS (image units), Gauss–Newton steps taken, whether it converged, pixels used. When it
    did not converge, (ds, dl) is the start."""

    ds: float
    dl: float
    gain: float
    offset: float
    sigma_px: tuple
    residual_rms: float
    iterations: int
    converged: bool
    n_pixels: int


def _bspline3(t):
    """Cubic B-spline β³(t) and its derivative (Unser 1999)."""
    a = np.abs(t)
    v = np.where(a < 1, 2 / 3 - a * a + 0.5 * a ** 3, np.where(a < 2, (2 - a) ** 3 / 6, 0.0))
    d = np.where(a < 1, -2 * t + 1.5 * t * a, np.where(a < 2, -np.sign(t) * (2 - a) ** 2 / 2, 0.0))
    return v, d


def spline_coefficients(template: np.ndarray, valid: np.ndarray, pad: int = 4, fill: str = "nearest") -> np.ndarray:
    """Cubic B-spline coefficients of the template on its grid padded by ``pad`` pixels on every side (so the
    spline interpolates every template pixel exactly). Outside the footprint, and in the padding, the template is
    continued by the nearest footprint pixel's value, or by the footprint mean with ``fill="mean"``."""
    from scipy.ndimage import distance_transform_edt, spline_filter

    t = np.asarray(template, float)
    v = np.asarray(valid, bool)
    if fill == "mean":
        filled = np.pad(np.where(v, t, float(t[v].mean())), pad, mode="constant", constant_values=float(t[v].mean()))
    else:
        vp = np.pad(v, pad, mode="constant", constant_values=False)
        _, (iy, ix) = distance_transform_edt(~vp, return_indices=True)
        filled = np.pad(t, pad, mode="constant")[iy, ix]
    return spline_filter(filled, order=3, mode="mirror")


def _weights(psi: float):
    """Tap offsets (−1..2 from floor) and the value / derivative weights of T(x − ψ) along one axis."""
    u = -float(psi)
    m = int(np.floor(u))
    f = u - m  # x - psi = x + m + f, f in [0, 1)
    k = np.arange(-1, 3)
    w, dw = _bspline3(f - k)
    return m + k, w, dw


def moved_with_gradient(coef: np.ndarray, shape, psi_sl, pad: int = 4):
    """``(T, ∂T/∂s, ∂T/∂l)`` of the spline at x − ψ on the template grid (``shape``), ψ = (ψs, ψl) px,
    |ψ| < ``pad`` − 2: separable four-tap sums of the coefficients (exact spline values and derivatives)."""
    h, w = shape
    ks, ws, dws = _weights(psi_sl[0])
    kl, wl, dwl = _weights(psi_sl[1])
    cols = [coef[:, pad + o:pad + o + w] for o in ks]  # along s (axis 1)
    vs = sum(wi * c for wi, c in zip(ws, cols))
    ds = sum(wi * c for wi, c in zip(dws, cols))
    rows = [slice(pad + o, pad + o + h) for o in kl]  # along l (axis 0)
    T = sum(wi * vs[r] for wi, r in zip(wl, rows))
    Ts = sum(wi * ds[r] for wi, r in zip(wl, rows))
    Tl = sum(wi * vs[r] for wi, r in zip(dwl, rows))
    return T, Ts, Tl


def _eroded(valid: np.ndarray, k: int) -> np.ndarray:
    from scipy.ndimage import binary_erosion

    v = np.asarray(valid, bool)
    if k == 0:
        return v.copy()
    return binary_erosion(v, structure=np.ones((2 * k + 1, 2 * k + 1), bool), border_value=0)


def _pixel_set(image, image_valid, valid, s0, l0, n, erode_px):
    """Template grid indices (y, x) of P and the image values there (module docstring)."""
    H, W = image.shape
    yy, xx = np.nonzero(_eroded(valid, erode_px))
    li, si = yy + l0 + n[1], xx + s0 + n[0]
    ok = (li >= 0) & (li < H) & (si >= 0) & (si < W)
    yy, xx, li, si = yy[ok], xx[ok], li[ok], si[ok]
    if image_valid is not None:
        keep = np.asarray(image_valid, bool)[li, si]
        yy, xx, li, si = yy[keep], xx[keep], li[keep], si[keep]
    e = np.asarray(image, float)[li, si]
    keep = np.isfinite(e)
    return yy[keep], xx[keep], e[keep]


def ml_shift(image, template, valid, s0: int, l0: int, ds: float, dl: float, image_valid=None,
             options: MlShiftOptions = MlShiftOptions()) -> MlShift:
    """The maximum-likelihood shift (Δs, Δl) of (ML-2) by Gauss–Newton from (``ds``, ``dl``) (module docstring).

    Parameters
    ----------
    image : (H, W) array
        The image I_e (DN).
    template, valid : (h, w) arrays
        The noise-free prediction T and its footprint, placed with its (0, 0) at image pixel (``s0``, ``l0``).
    ds, dl : float
        Start (px), e.g. a peak finder's estimate; the shift convention of :mod:`estimators.landmarks.peaks` (content of the
        template at x appears at x + δ in the image).
    image_valid : (H, W) bool or None
        Usable image pixels.

    Raises
    ------
    ValueError
        Shapes that do not match, an empty footprint or a non-finite start.
    """
    t = np.asarray(template, float)
    v = np.asarray(valid, bool)
    img = np.asarray(image, float)
    if t.ndim != 2 or v.shape != t.shape or img.ndim != 2 or (image_valid is not None
                                                                 and np.shape(image_valid) != img.shape):
        raise ValueError(f"ml_shift: template {t.shape}, footprint {v.shape}, image {img.shape} and image mask "
                         f"{None if image_valid is None else np.shape(image_valid)} do not match")
    if not v.any() or not (np.isfinite(ds) and np.isfinite(dl)):
        raise ValueError("ml_shift: empty footprint or non-finite start")
    start = np.array([ds, dl], float)
    n = (int(np.round(ds)), int(np.round(dl)))
    yy, xx, e = _pixel_set(img, image_valid, v, int(s0), int(l0), n, options.erode_px)
    fail = MlShift(float(ds), float(dl), float("nan"), float("nan"), (float("nan"),) * 2, float("nan"), 0, False,
                   int(e.size))
    if e.size < options.min_pixels:
        return fail
    pad = int(np.ceil(options.max_move_px + 0.5)) + 3
    coef = spline_coefficients(t, v, pad, options.fill)
    delta = start.copy()
    a = b = 0.0
    for it in range(1, options.iterations + 1):
        T, Ts, Tl = (g[yy, xx] for g in moved_with_gradient(coef, t.shape, delta - n, pad))
        if it == 1:  # gain and offset at the start: linear least squares
            A = np.column_stack([T, np.ones_like(T)])
            a, b = np.linalg.lstsq(A, e, rcond=None)[0]
            if not a > 0:
                return fail
        r = e - (a * T + b)
        J = np.column_stack([-a * Ts, -a * Tl, T, np.ones_like(T)])
        JtJ = J.T @ J
        if not np.linalg.cond(JtJ) < 1e12:  # no gain, or no gradient: the shift is not observable
            return fail
        step = np.linalg.solve(JtJ, J.T @ r)
        delta = delta + np.clip(step[:2], -0.5, 0.5)
        a, b = a + step[2], b + step[3]
        if not (a > 0 and np.all(np.abs(delta - start) <= options.max_move_px)):
            return fail
        if np.max(np.abs(step[:2])) < options.tol_px:
            break
    else:
        return fail
    T, Ts, Tl = (g[yy, xx] for g in moved_with_gradient(coef, t.shape, delta - n, pad))
    r = e - (a * T + b)
    J = np.column_stack([-a * Ts, -a * Tl, T, np.ones_like(T)])
    s2 = float(r @ r) / max(e.size - 4, 1)
    try:
        cov = s2 * np.linalg.inv(J.T @ J)
        sig = (float(np.sqrt(cov[0, 0])), float(np.sqrt(cov[1, 1])))
    except np.linalg.LinAlgError:
        sig = (float("inf"),) * 2
    return MlShift(float(delta[0]), float(delta[1]), float(a), float(b), sig, float(np.sqrt(s2)), it, True,
                   int(e.size))


def refine_ml(image, template, valid, s0: int, l0: int, ds: float, dl: float, image_valid=None,
              min_pixels: int = 16) -> tuple[float, float]:
    """(Δs, Δl) of :func:`ml_shift` from (``ds``, ``dl``); the start where it does not converge (a refinement of
    :data:`REFINEMENTS`)."""
    r = ml_shift(image, template, valid, s0, l0, ds, dl, image_valid, MlShiftOptions(min_pixels=max(5, min_pixels)))
    return r.ds, r.dl


#: registered refinements after the peak finder (and re-centred passes): name → f(image, template, valid, s0, l0,
#: ds, dl, image_valid, min_pixels) → (ds, dl); ``RetinaOptions.refine`` names one
REFINEMENTS = {"ml_shift": refine_ml}
