r"""Registration Cramér–Rao bound of a continuous (band-limited) template over exactly the estimator's pixels.

The bound a shift estimator is compared with is that of the *continuous* scene it registers, pixel-integrated the
way the detector integrates it, over the pixels the estimator reads — not finite differences of the sampled pixels
(which miss the gradient energy of texture near and above the pixel Nyquist frequency) over a larger square window.

Model (pixel coordinates x = s, y = l; pixel j has its centre at x = j and covers [j − ½, j + ½]):

(1) scene radiance f(x, y), continuous, band-limited at the sampling of its supersampled render;
(2) noise-free pixel value ``μᵢ(θ) = a·P(sᵢ − δs, lᵢ − δl) + b`` with ``P = f * Π * G_σ`` (Π the unit pixel box,
    G_σ an optional Gaussian PSF of σ px), θ = (δs, δl) and, optionally, the nuisances gain a and offset b
    (true values a = 1, b = 0);
(3) the template is known from k × k sub-pixel samples per pixel: ``g = f * Π_{1/k}`` at the sub-pixel centres
    (``sample="area"``, a renderer's sub-pixel averages) or ``g = f`` there (``sample="point"``);
(4) in the Fourier domain of the fine grid (u, v in cycles per pixel):
    ``P̂(u, v) = ĝ(u, v) · H(u) H(v) · exp(−2π²σ²(u² + v²))`` with ``H(u) = sinc(u)/sinc(u/k)`` (area) or
    ``sinc(u)`` (point), sinc(x) = sin(πx)/(πx);
(5) the derivatives, analytic in the Fourier domain, evaluated at the pixel centres:
    ``∂μ/∂δs = −a·F⁻¹[2πi u P̂]``, ``∂μ/∂δl = −a·F⁻¹[2πi v P̂]``, ``∂μ/∂a = P``, ``∂μ/∂b = 1``;
(6) Poisson + read noise: the DN of pixel i has variance ``vᵢ = μₑ,ᵢ/g² + σ_r²/g² (+ 1/12)`` (electrons μₑ, gain
    g e⁻/DN, read noise σ_r e⁻; :func:`renderlab.campaign.scoring.dn_variance`); the Fisher information over the
    estimator's pixels F is ``J = Σ_{i∈F} ∇_θμᵢ ∇_θμᵢᵀ / vᵢ`` — the Gaussian one at the true variance. The
    term of the variance's own dependence on θ, ``(∂vᵢ)²/(2vᵢ²)``, is left out: relative to the mean's term it is
    ``1/(2 vᵢ)`` in electrons (≤ 0.5 % above 100 e⁻), and the Poisson–Gaussian law's exact information lies
    between ``(∂μ)²/(μ + σ_r²)`` and ``(∂μ)²/μ`` in electrons;
(7) the bound ``C = J⁻¹`` (nuisances included: the shift block of the full inverse), σ_s = √C₀₀, σ_l = √C₁₁.

The fine image is extended by mirroring before the transform (continuous at its border, so the periodic
transform rings little); the pixels used should keep a margin of a few pixels from the crop's edge.

Against a closed-form Fisher information (a pixel-integrated Gaussian blob, gratings near the Nyquist frequency, a
random band-limited texture) and a maximum-likelihood shift on Poisson + read-noise draws:
``tests/test_crlb_continuous.py``.

References: Kay, S. M. (1993) *Fundamentals of Statistical Signal Processing: Estimation Theory*, Prentice Hall,
ch. 3 (Fisher information of a Gaussian model, eq. 3.31) — ISBN 0-13-345711-7; Robinson, D. & Milanfar, P. (2004)
"Fundamental performance limits in image registration", IEEE Trans. Image Process. 13(9), 1185–1199,
doi:10.1109/TIP.2004.832923.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass

import numpy as np

from renderlab.campaign.scoring import registration_crlb

NUISANCES = ("gain", "offset")


@dataclass(frozen=True)
class ContinuousCrlb:
    """Result of :func:`continuous_crlb`.

    Attributes
    ----------
    sigma : (float, float)
        (σ_s, σ_l) px, eq. 7; ∞ where J is singular.
    fisher : ndarray (n, n)
        J of eq. 6, parameters (δs, δl, then the nuisances in the order given).
    parameters : tuple of str
        Names of J's rows.
    pixels : int
        Pixels used (the footprint's, with finite variance).
    """

    sigma: tuple[float, float]
    fisher: np.ndarray
    parameters: tuple[str, ...]
    pixels: int


def _transfer(n: int, k: int, sample: str, psf_sigma_px: float) -> tuple[np.ndarray, np.ndarray]:
    """(u cycles/px, H(u)·exp(−2π²σ²u²)) of eq. 4 along one axis of ``n`` fine samples."""
    u = np.fft.fftfreq(n, d=1.0 / k)
    h = np.sinc(u) / np.sinc(u / k) if sample == "area" else np.sinc(u)
    return u, h * np.exp(-2.0 * math.pi ** 2 * psf_sigma_px ** 2 * u * u)


def template_derivatives(fine: np.ndarray, k: int, *, sample: str = "area",
                         psf_sigma_px: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The pixel-integrated template and its shift derivatives at the pixel centres (eqs. 4–5, a = 1).

    Parameters
    ----------
    fine : ndarray (k·H, k·W)
        The scene sampled k × k times per pixel (eq. 3), same units as the pixels (e.g. expected DN).
    k : int
        Samples per pixel along each axis.
    sample : {"area", "point"}
        What a fine sample is: the mean over its sub-pixel (a renderer's) or the scene at its centre.
    psf_sigma_px : float
        Gaussian PSF σ, pixels (0: none).

    Returns
    -------
    (P, ∂P/∂s, ∂P/∂l) : ndarrays (H, W)
        The template, and its derivatives along s (columns) and l (rows), per pixel.
    """
    g = np.asarray(fine, float)
    k = int(k)
    if k < 1 or g.ndim != 2 or g.shape[0] % k or g.shape[1] % k:
        raise ValueError(f"fine image {g.shape} is not k·H × k·W for k = {k}")
    if sample not in ("area", "point"):
        raise ValueError(f"sample must be 'area' or 'point', got {sample!r}")
    n0, n1 = g.shape
    ext = np.pad(g, ((0, n0), (0, n1)), mode="symmetric")  # even extension: continuous at the border
    G = np.fft.fft2(ext)
    v, hv = _transfer(2 * n0, k, sample, psf_sigma_px)
    u, hu = _transfer(2 * n1, k, sample, psf_sigma_px)
    # fine sample p sits at x = (p + ½)/k − ½: shift by o = (1 − k)/(2k) so that index j·k reads pixel centre j
    o = (1.0 - k) / (2.0 * k)
    pu, pv = hu * np.exp(-2j * math.pi * u * o), hv * np.exp(-2j * math.pi * v * o)
    Ph = G * pv[:, None] * pu[None, :]
    out = []
    for spec in (Ph, Ph * (2j * math.pi * u)[None, :], Ph * (2j * math.pi * v)[:, None]):
        out.append(np.real(np.fft.ifft2(spec))[:n0:k, :n1:k])
    return out[0], out[1], out[2]


def shift_fisher(template: np.ndarray, d_s: np.ndarray, d_l: np.ndarray, variance, mask=None, *,
                 nuisances: tuple[str, ...] = (), independent: tuple | None = None) -> tuple[np.ndarray, int]:
    """J of eq. 6 over the pixels of ``mask`` → (J, pixels).

    ``template``, ``d_s``, ``d_l``: :func:`template_derivatives`; ``variance``: DN² per pixel (or a scalar);
    ``nuisances``: any of ``"gain"``, ``"offset"``. ``independent``: the same three arrays of a second render of
    the scene with independent Monte-Carlo noise; J is then the symmetrised cross-product
    ``Σ w (∇μ¹ ∇μ²ᵀ + ∇μ² ∇μ¹ᵀ)/2``, unbiased for the noise-free scene's J (one render's own product adds its
    noise's gradient energy).
    """
    bad = [n for n in nuisances if n not in NUISANCES]
    if bad:
        raise ValueError(f"unknown nuisance {bad[0]!r} (known: {', '.join(NUISANCES)})")
    P = np.asarray(template, float)
    var = np.broadcast_to(np.asarray(variance, float), P.shape)
    m = np.ones(P.shape, bool) if mask is None else np.asarray(mask, bool)
    m = m & np.isfinite(var) & (var > 0)

    def columns(t, ds, dl):
        cols = [-np.asarray(ds, float)[m], -np.asarray(dl, float)[m]]
        for n in nuisances:
            cols.append(np.asarray(t, float)[m] if n == "gain" else np.ones(int(m.sum())))
        return np.stack(cols, 1)

    w = 1.0 / var[m]
    A = columns(P, d_s, d_l)
    if independent is None:
        J = (A * w[:, None]).T @ A
    else:
        B = columns(*independent)
        J = 0.5 * ((A * w[:, None]).T @ B + (B * w[:, None]).T @ A)
    return J, int(m.sum())


def sigma_from_fisher(J: np.ndarray) -> tuple[float, float]:
    """(σ_s, σ_l) of eq. 7: √ of the first two diagonal terms of J⁻¹; ∞ where J is not positive definite."""
    J = np.asarray(J, float)
    d = np.sqrt(np.clip(np.diag(J), 1e-300, None))
    Jn = J / np.outer(d, d)  # scaled: the nuisances' units do not matter for the test
    ev = np.linalg.eigvalsh(Jn)
    if not np.all(np.isfinite(Jn)) or ev[0] <= 1e-12 * ev[-1] or np.any(np.diag(J) <= 0):
        return math.inf, math.inf
    C = np.linalg.inv(Jn) / np.outer(d, d)
    return float(math.sqrt(C[0, 0])), float(math.sqrt(C[1, 1]))


def continuous_crlb(fine: np.ndarray, k: int, variance, mask=None, *, sample: str = "area",
                    psf_sigma_px: float = 0.0, nuisances: tuple[str, ...] = (),
                    independent: np.ndarray | None = None) -> ContinuousCrlb:
    """The registration CRLB (eqs. 1–7) of the template sampled in ``fine`` over the pixels of ``mask``.

    Parameters
    ----------
    fine : ndarray (k·H, k·W)
        The scene sampled k × k times per pixel (eq. 3), in DN (the units of ``variance``'s square root).
    k : int
        Samples per pixel along each axis (1: the pixel image itself taken as band-limited, exact only for a
        scene without content above the pixel Nyquist frequency).
    variance : float or ndarray (H, W)
        Noise variance of each pixel, DN² (eq. 6).
    mask : ndarray of bool (H, W), optional
        The estimator's pixels (default: all); keep a few pixels' margin from the crop's edge.
    sample, psf_sigma_px
        See :func:`template_derivatives`.
    nuisances : tuple of str
        ``"gain"`` and/or ``"offset"`` estimated jointly with the shift.
    independent : ndarray (k·H, k·W), optional
        A second render of the same scene with independent render noise (cross-product J, :func:`shift_fisher`).
    """
    P, ds, dl = template_derivatives(fine, k, sample=sample, psf_sigma_px=psf_sigma_px)
    other = None if independent is None else template_derivatives(independent, k, sample=sample,
                                                                   psf_sigma_px=psf_sigma_px)
    J, n = shift_fisher(P, ds, dl, variance, mask, nuisances=tuple(nuisances), independent=other)
    return ContinuousCrlb(sigma_from_fisher(J), J, ("ds", "dl", *nuisances), n)


# ------------------------------------------------------------------- the bound of a landmark on a rendered truth
def fine_truth_dict(truth: dict, k: int, spp: int | None = None) -> dict:
    """A truth scenario's dict rendered at k × k sub-pixels per pixel (the ``fine`` image of eq. 3): width/height and
    fx/fy × k, the principal point on the same spot ((c + ½)·k − ½), a site's tile levels unchanged (``lod_pixels``
    × k), ``spp`` samples per sub-pixel (None: the scenario's). Needs an undistorted pinhole camera."""
    d = copy.deepcopy(truth)
    if spp is not None:
        d["render"]["spp"] = int(spp)
    cam = d["camera"]
    if cam.get("distortion") or cam.get("model", "pinhole") != "pinhole" or cam.get("skew") or cam.get("skew_yx"):
        raise ValueError("fine_truth_dict needs an undistorted pinhole camera")
    for a in ("width", "height"):
        cam[a] = int(cam[a]) * int(k)
    for a in ("fx", "fy"):
        cam[a] = float(cam[a]) * k
    for a in ("cx", "cy"):
        cam[a] = (float(cam[a]) + 0.5) * k - 0.5
    site = d.get("world", {}).get("site")
    if isinstance(site, dict):
        site["lod_pixels"] = float(site.get("lod_pixels", 1.0)) * k
    return d


def footprint_bound(fine_dn: np.ndarray, k: int, variance: np.ndarray, footprint, *, margin: int = 6,
                    nuisances: tuple[str, ...] = (), independent: np.ndarray | None = None) -> ContinuousCrlb | None:
    """:func:`continuous_crlb` of a frame's fine expected DN (k·H × k·W) over a footprint ``(l0, s0, valid (h, w))``
    of the pixels an estimator reads (None: no bound), on a crop of ``margin`` pixels around it (clipped to the
    image); None where fewer than 8 pixels are left."""
    if footprint is None:
        return None
    l0, s0, valid = footprint
    H, W = variance.shape
    h, w = valid.shape
    r0, r1 = max(l0 - margin, 0), min(l0 + h + margin, H)
    c0, c1 = max(s0 - margin, 0), min(s0 + w + margin, W)
    mask = np.zeros((r1 - r0, c1 - c0), bool)
    mask[l0 - r0:l0 - r0 + h, s0 - c0:s0 - c0 + w] = valid
    if mask.sum() < 8:
        return None
    fsl = (slice(r0 * k, r1 * k), slice(c0 * k, c1 * k))
    return continuous_crlb(fine_dn[fsl], k, variance[r0:r1, c0:c1], mask, nuisances=nuisances,
                           independent=None if independent is None else independent[fsl])


def sigma_or_nan(res: ContinuousCrlb | None) -> tuple[float, float]:
    """(σ_s, σ_l) of a bound, NaN where there is none."""
    return (math.nan, math.nan) if res is None else res.sigma


def crlb_window(s: float, l: float, gsd_ratio, size: int, shape: tuple[int, int]):
    """The square window of the finite-difference bound around the landmark at (s, l) that spans a maplet of ``size``
    posts at GSD ratio ``gsd_ratio`` (half-size ½·(size − 1)/GSD ratio, ≥ 3 px, clipped to ``shape``) → (row slice,
    column slice), or None where undefined or under 7 px either way."""
    if not (np.isfinite(s) and np.isfinite(l) and gsd_ratio is not None and np.isfinite(gsd_ratio) and gsd_ratio > 0):
        return None
    half = int(max(3, math.ceil(0.5 * (size - 1) / gsd_ratio)))
    c0, r0 = int(round(s)), int(round(l))
    win = (slice(max(r0 - half, 0), min(r0 + half + 1, shape[0])), slice(max(c0 - half, 0), min(c0 + half + 1, shape[1])))
    return win if min(win[0].stop - win[0].start, win[1].stop - win[1].start) >= 7 else None


def window_crlb(expected: np.ndarray, variance: np.ndarray, s: float, l: float, gsd_ratio, size: int) -> tuple:
    """The finite-difference bound (:func:`~renderlab.campaign.scoring.registration_crlb`) of the truth pixels
    ``expected`` over :func:`crlb_window`; NaN where there is no window."""
    win = crlb_window(s, l, gsd_ratio, size, expected.shape)
    return (math.nan, math.nan) if win is None else registration_crlb(expected[win], variance[win])
