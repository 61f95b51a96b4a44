"""Scoring campaign tables: errors against truth, bias, noise, robust statistics, failure rates, CRLB.

Measurement tables (:data:`renderlab.contracts.schemas.LANDMARK_CORE`): ``err = meas − truth`` per axis (s, l)
and method. Per group:
bias = mean (Student-t confidence interval), noise = standard deviation (χ² interval, normal errors),
robust versions median (binomial order-statistic interval) and MAD·1.4826 (σ for normal errors),
RMS, and the no-result rate (rows with ``has_result`` false or a NaN measurement; Wilson interval). Breakdowns repeat this per quantile bin of a covariate (phase angle, GSD ratio, shadow
fraction, albedo contrast, range).

Image-registration Cramér–Rao bound: for an image I(s − δs, l − δl) of a known scene in independent
Gaussian pixel noise of variance σ²ᵢ, the Fisher information of the shift is
``J = Σᵢ ∇Iᵢ ∇Iᵢᵀ / σ²ᵢ`` and any unbiased shift estimate has ``cov ≥ J⁻¹``. With uncorrelated
gradients this is the single-axis ``σ²/Σ(∂I/∂s)²`` of the issue. ∇I is the central difference of the
noise-free expected DN (4th-order stencil); σ² comes from the sensor model (shot + dark electrons, read noise, gain,
1/12 DN² quantisation). It bounds the correlation shift of Wright et al. eq. 9 and any centroid.
When the expected image is itself a Monte-Carlo render (finite samples per pixel), its render noise adds
gradient energy and the bound comes out too small; ``registration_crlb(..., independent=second_render)`` takes
the cross-product of two independent renders' gradients, an unbiased estimate of the noise-free J
(:func:`fisher_information`). This finite-difference bound of the sampled pixels is what the published tables made
before :mod:`renderlab.campaign.crlb` carry (the error budget's CRLB probe reproduces them with it) and what the
``analytic_pointing`` study still computes; on sub-pixel texture it misses gradient energy (too large: 2.1–16× the
exact bound on the sub-pixel textures of ``tests/test_crlb_continuous.py``, 1.06× on its smooth blob). New ``retina_vs_spc`` runs use the
bound of the continuous template over the estimator's pixels (:mod:`renderlab.campaign.crlb`).

Filter tables (``run, t_s, err_*``, ``nees``, ``nis``): per error column mean/std/RMS after a settling
time, and ANEES/ANIS with their two-sided χ² bounds (N runs × d degrees of freedom).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from renderlab.contracts.schemas import table_kind as kind
from renderlab.sensor.model import mean_electrons

BREAKDOWNS = ("phase_deg", "gsd_ratio", "shadow_fraction", "albedo_contrast", "range_m")


def table_kind(table) -> str:
    """The registered observable kind of a table, or ``"other"`` (:func:`renderlab.contracts.schemas.table_kind`)."""
    return kind(table)


def score_table(table, *, confidence: float = 0.95) -> list[dict]:
    """Summary rows of a table by its registered kind's ``scorer(table, *, confidence)``
    (:mod:`renderlab.contracts.observable`); ``[]`` for a table of no kind or of a kind without a scorer."""
    from renderlab import plugins

    name = kind(table)
    scorer = None if name == "other" else plugins.observable(name).part("scorer")
    return [] if scorer is None else list(scorer(table, confidence=confidence))


# ------------------------------------------------------------------------------ statistics
@dataclass(frozen=True)
class Stats:
    """Statistics of one error sample (NaNs removed); intervals at ``confidence``."""

    n: int
    mean: float
    mean_lo: float
    mean_hi: float
    std: float
    std_lo: float
    std_hi: float
    median: float
    median_lo: float
    median_hi: float
    mad: float
    rms: float


def error_stats(x, confidence: float = 0.95) -> Stats:
    """Bias, noise, robust statistics and their confidence intervals of the finite values of ``x``."""
    from scipy import stats

    x = np.sort(np.asarray(x, float)[np.isfinite(np.asarray(x, float))])
    n = len(x)
    nan = math.nan
    if n == 0:
        return Stats(0, *([nan] * 11))
    a = 1.0 - confidence
    mean, med = float(x.mean()), float(np.median(x))
    rms = float(np.sqrt(np.mean(x * x)))
    mad = float(1.482602218505602 * np.median(np.abs(x - med)))
    if n < 2:
        return Stats(n, mean, nan, nan, nan, nan, nan, med, nan, nan, mad, rms)
    sd = float(x.std(ddof=1))
    half = float(stats.t.ppf(1 - a / 2, n - 1)) * sd / math.sqrt(n)
    q = (n - 1) * sd * sd
    std_lo, std_hi = math.sqrt(q / stats.chi2.ppf(1 - a / 2, n - 1)), math.sqrt(q / stats.chi2.ppf(a / 2, n - 1))
    j = int(stats.binom.ppf(a / 2, n, 0.5))  # order statistics x_(j), x_(n-j+1), 1-based
    med_lo, med_hi = (float(x[j - 1]), float(x[n - j])) if j >= 1 else (nan, nan)
    return Stats(n, mean, mean - half, mean + half, sd, std_lo, std_hi, med, med_lo, med_hi, mad, rms)


def proportion_ci(k: int, n: int, confidence: float = 0.95) -> tuple[float, float, float]:
    """Rate ``k/n`` and its Wilson score interval."""
    from scipy import stats

    if n == 0:
        return math.nan, math.nan, math.nan
    z = float(stats.norm.ppf(1 - (1 - confidence) / 2))
    p = k / n
    den = 1 + z * z / n
    mid = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return p, min(p, max(0.0, mid - half)), max(p, min(1.0, mid + half))


# ------------------------------------------------------------------------ measurement scoring
def column_array(table, name, dtype=float) -> np.ndarray:
    """Column ``name`` of a pyarrow table as a numpy array of ``dtype``."""
    return np.asarray(table.column(name).to_numpy(zero_copy_only=False), dtype)


def no_result_mask(table) -> np.ndarray:
    """Rows where the method gave no measurement (``has_result`` false or a NaN measurement)."""
    has = column_array(table, "has_result", bool)
    return ~has | ~np.isfinite(column_array(table, "meas_s")) | ~np.isfinite(column_array(table, "meas_l"))


def _group_rows(table, mask, keys: dict, confidence: float) -> list[dict]:
    rows = []
    failed = no_result_mask(table)[mask]
    rate, rate_lo, rate_hi = proportion_ci(int(failed.sum()), int(mask.sum()), confidence)
    for axis in ("s", "l"):
        err = column_array(table, f"err_{axis}")[mask][~failed]
        st = error_stats(err, confidence)
        row = {**keys, "axis": axis, "n_rows": int(mask.sum()), "n_result": st.n,
               "no_result_rate": rate, "no_result_lo": rate_lo, "no_result_hi": rate_hi,
               **{f"{k}": getattr(st, k) for k in Stats.__dataclass_fields__ if k != "n"}}
        if f"crlb_{axis}" in table.column_names:
            c = column_array(table, f"crlb_{axis}")[mask][~failed]
            c = c[np.isfinite(c)]
            row["crlb_rms"] = float(np.sqrt(np.mean(c * c))) if len(c) else math.nan
            row["std_over_crlb"] = st.std / row["crlb_rms"] if len(c) and row["crlb_rms"] > 0 else math.nan
        if "t_ms" in table.column_names:
            row["t_ms_median"] = float(np.nanmedian(column_array(table, "t_ms")[mask])) if mask.any() else math.nan
        rows.append(row)
    return rows


def score_measurements(table, confidence: float = 0.95) -> list[dict]:
    """Summary rows per (method, axis): bias, noise, robust stats, intervals, no-result rate, CRLB ratio."""
    methods = column_array(table, "method", object)
    rows = []
    for m in sorted(set(methods)):
        rows += _group_rows(table, methods == m, {"method": m}, confidence)
    return rows


def breakdown(table, column: str, bins: int = 4, confidence: float = 0.95) -> list[dict]:
    """Summary rows per (method, quantile bin of ``column``, axis); empty if the column is absent."""
    if column not in table.column_names:
        return []
    v = column_array(table, column)
    fin = np.isfinite(v)
    if fin.sum() == 0:
        return []
    edges = np.unique(np.quantile(v[fin], np.linspace(0, 1, bins + 1)))
    if len(edges) < 2:
        edges = np.array([v[fin].min(), v[fin].max()])
    idx = np.clip(np.searchsorted(edges, v, side="right") - 1, 0, len(edges) - 2)
    methods = column_array(table, "method", object)
    rows = []
    for m in sorted(set(methods)):
        for b in range(len(edges) - 1):
            mask = (methods == m) & fin & (idx == b)
            if mask.any():
                keys = {"method": m, "by": column, "bin": b, "lo": float(edges[b]), "hi": float(edges[b + 1]),
                        "center": float(np.median(v[mask]))}
                rows += _group_rows(table, mask, keys, confidence)
    return rows


# ----------------------------------------------------------------------------- CRLB
def dn_variance(radiance: np.ndarray, options) -> np.ndarray:
    """Per-pixel DN noise variance of :func:`renderlab.sensor.model.expose`: (μₑ + σ_read²)/g² + 1/12."""
    mu = np.minimum(mean_electrons(np.asarray(radiance, float), options), float(options.full_well_e))
    return (mu + float(options.read_noise_e) ** 2) / float(options.gain_e_per_dn) ** 2 + 1.0 / 12.0


#: 4th-order central-difference stencil of the CRLB gradients (correlated, so the centre weight is 0)
GRADIENT_STENCIL = np.array([1.0, -8.0, 0.0, 8.0, -1.0]) / 12.0


def image_gradients(img: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(∂I/∂s, ∂I/∂l) by :data:`GRADIENT_STENCIL`; the two border rows/columns each side are NaN."""
    from scipy.ndimage import correlate1d

    gs = correlate1d(img, GRADIENT_STENCIL, axis=1, mode="nearest")
    gl = correlate1d(img, GRADIENT_STENCIL, axis=0, mode="nearest")
    gs[:, [0, 1, -2, -1]] = np.nan  # the stencil needs two neighbours each side:
    gl[[0, 1, -2, -1], :] = np.nan  # border pixels are left out
    return gs, gl


def fisher_information(expected: np.ndarray, variance, *, independent: np.ndarray | None = None) -> np.ndarray:
    """2 × 2 Fisher information J of the (s, l) shift (see :func:`registration_crlb`).

    Without ``independent``: ``J = Σᵢ wᵢ ∇Iᵢ ∇Iᵢᵀ``, wᵢ = 1/σ²ᵢ, ∇I of ``expected``. With ``independent`` (a
    second image of the same expectation whose noise is independent of ``expected``'s, e.g. a render with
    another seed): the cross-product ``J = Σᵢ wᵢ (∇I¹ᵢ ∇I²ᵢᵀ + ∇I²ᵢ ∇I¹ᵢᵀ)/2``. For images ``Ī + εᵏ`` with
    zero-mean noise independent between the copies, E[∇I¹ ∇I²ᵀ] = ∇Ī ∇Īᵀ, so the cross-product is an unbiased
    estimate of the noise-free image's J, whereas one copy's E[∇I ∇Iᵀ] = ∇Ī ∇Īᵀ + Cov(∇ε) adds the noise's
    gradient energy (Σ c² = 130/144 of the pixel noise variance per axis for pixel-independent noise) and
    overstates J. The cross-product is not positive definite where the noise dominates the window.
    """
    img = np.asarray(expected, float)
    gs, gl = image_gradients(img)
    w = 1.0 / np.broadcast_to(np.asarray(variance, float), img.shape)
    if independent is None:
        hs, hl = gs, gl
    else:
        other = np.asarray(independent, float)
        if other.shape != img.shape:
            raise ValueError(f"independent image shape {other.shape} differs from expected {img.shape}")
        hs, hl = image_gradients(other)
    ok = np.isfinite(gs) & np.isfinite(gl) & np.isfinite(hs) & np.isfinite(hl) & np.isfinite(w)
    ss = np.sum((w * gs * hs)[ok])
    ll = np.sum((w * gl * hl)[ok])
    sl = 0.5 * (np.sum((w * gs * hl)[ok]) + np.sum((w * hs * gl)[ok])) if independent is not None \
        else np.sum((w * gs * gl)[ok])
    return np.array([[ss, sl], [sl, ll]])


def crlb_from_fisher(J: np.ndarray, *, full: bool = True) -> tuple[float, float]:
    """(σ_s, σ_l) px from a 2 × 2 Fisher information: √diag J⁻¹ (``full``) or 1/√J_kk; ∞ where J is not
    positive definite (or its diagonal term is ≤ 0)."""
    if not full:
        return (1 / math.sqrt(J[0, 0]) if J[0, 0] > 0 else math.inf, 1 / math.sqrt(J[1, 1]) if J[1, 1] > 0 else math.inf)
    if J[0, 0] <= 0 or J[1, 1] <= 0 or np.linalg.det(J) <= 1e-12 * max(J[0, 0] * J[1, 1], 1e-300):
        return math.inf, math.inf
    C = np.linalg.inv(J)
    return float(math.sqrt(C[0, 0])), float(math.sqrt(C[1, 1]))


def registration_crlb(expected: np.ndarray, variance, *, full: bool = True,
                      independent: np.ndarray | None = None) -> tuple[float, float]:
    """Cramér–Rao bound (1σ, px) of the (s, l) shift of a known image in Gaussian pixel noise.

    Parameters
    ----------
    expected : ndarray (H, W)
        Noise-free expected image (e.g. DN) over the registration window.
    variance : float or ndarray (H, W)
        Pixel noise variance, same units squared.
    full : bool
        True: sqrt of the diagonal of ``J⁻¹`` (joint s, l estimation); False: the single-axis
        ``sqrt(σ²/Σ(∂I/∂s)²)`` form (equal when the gradients are uncorrelated).
    independent : ndarray (H, W), optional
        When ``expected`` is itself noisy (a Monte-Carlo render at finite samples per pixel), a second render
        of the same scene with independent noise: J is then the cross-product of the two renders' gradients
        (:func:`fisher_information`), unbiased for the noise-free image's J, where the gradients of one noisy
        render overstate J and so understate the bound. Default: one image, the bound of ``expected`` as given.
    """
    return crlb_from_fisher(fisher_information(expected, variance, independent=independent), full=full)


def template_shift_covariance(template: np.ndarray, image: np.ndarray, variance, mask=None) -> dict:
    """Noise of a shift estimated by matching a model ``template`` to ``image``, against the image's own bound.

    A correlation or least-squares registration with template t (gain and offset fitted) converges where
    Σ w ∇t (I − t) = 0; linearised about the true shift its noise is the sandwich
    ``cov = H⁻¹ B H⁻ᵀ`` with ``H = Σ w ∇t ∇Iᵀ`` (the curvature, over the true image I) and ``B = Σ w ∇t ∇tᵀ``
    (the noise projected on the template's gradients), w = 1/σ². With t = I it is J⁻¹, the CRLB
    (:func:`registration_crlb`); otherwise larger (Cauchy–Schwarz): the template's gradients that the image
    lacks, and the image's that the template lacks, cost information.

    Parameters
    ----------
    template, image : ndarray (H, W)
        The model prediction and the noise-free image over the same pixels.
    variance : float or ndarray (H, W)
        Pixel noise variance of the image.
    mask : ndarray of bool (H, W), optional
        The template's valid pixels (default all); only pixels with ±2 valid neighbours along both axes are
        used (the gradient stencil's reach), and the gain/offset fit uses every valid pixel.

    Returns
    -------
    dict
        ``sandwich`` (σ_s, σ_l) px; ``crlb`` (σ_s, σ_l): the image's bound over the same pixels; ``rho``
        (s, l): correlation of the template's and the image's gradients; ``pixels`` used. NaN where H or J is
        singular or fewer than 8 pixels remain.
    """
    from scipy.ndimage import binary_erosion

    t = np.asarray(template, float)
    img = np.asarray(image, float)
    m = np.ones(t.shape, bool) if mask is None else np.asarray(mask, bool)
    nan2 = (math.nan, math.nan)
    out = {"sandwich": nan2, "crlb": nan2, "rho": nan2, "pixels": 0}
    if m.sum() < 8:
        return out
    gain, offset = np.linalg.lstsq(np.c_[t[m], np.ones(int(m.sum()))], img[m], rcond=None)[0]
    t = np.where(m, gain * t + offset, 0.0)
    cross = np.zeros((5, 5), bool)
    cross[2, :] = cross[:, 2] = True
    use = binary_erosion(m, cross, border_value=0)
    gts, gtl = image_gradients(t)
    gis, gil = image_gradients(img)
    use &= np.isfinite(gts) & np.isfinite(gtl) & np.isfinite(gis) & np.isfinite(gil)
    out["pixels"] = int(use.sum())
    if use.sum() < 8:
        return out
    w = 1.0 / np.broadcast_to(np.asarray(variance, float), img.shape)[use]
    Gt, Gi = np.c_[gts[use], gtl[use]], np.c_[gis[use], gil[use]]
    H, B, J = (Gt * w[:, None]).T @ Gi, (Gt * w[:, None]).T @ Gt, (Gi * w[:, None]).T @ Gi
    if abs(np.linalg.det(H)) <= 1e-12 * abs(H[0, 0] * H[1, 1]) or np.linalg.det(J) <= 1e-12 * J[0, 0] * J[1, 1]:
        return out
    Hi = np.linalg.inv(H)
    out["sandwich"] = tuple(float(v) for v in np.sqrt(np.diag(Hi @ B @ Hi.T)))
    out["crlb"] = tuple(float(v) for v in np.sqrt(np.diag(np.linalg.inv(J))))
    out["rho"] = tuple(float(np.corrcoef(Gt[:, j], Gi[:, j])[0, 1]) for j in (0, 1))
    return out


# ----------------------------------------------------------------------------- filter scoring
def score_filter(table, *, settle_s: float = 0.0, nees_dof: int = 6, nis_dof: int = 2,
                 confidence: float = 0.95) -> list[dict]:
    """Rows per error column (after ``t_s ≥ settle_s``), plus ANEES/ANIS with χ² bounds."""
    from scipy import stats

    t = column_array(table, "t_s")
    keep = t >= settle_s
    runs = column_array(table, "run", np.int64)[keep]
    n_runs = len(np.unique(runs))
    rows = []
    for name in table.column_names:
        if name.startswith("err_"):
            st = error_stats(column_array(table, name)[keep], confidence)
            rows.append({"quantity": name, "n": st.n, "mean": st.mean, "mean_lo": st.mean_lo, "mean_hi": st.mean_hi,
                         "std": st.std, "rms": st.rms, "median": st.median, "mad": st.mad})
    a = 1 - confidence
    for name, dof in (("nees", nees_dof), ("nis", nis_dof)):
        if name in table.column_names and n_runs:
            v = column_array(table, name)[keep]
            ts = t[keep]
            # average over the runs that have a value at each time (NIS is missing where an image gave
            # no measurement), each time against the χ² band of its own count
            inside_t = []
            for tt in np.unique(ts):
                vt = v[(ts == tt) & np.isfinite(v)]
                if vt.size:
                    lo_t, hi_t = stats.chi2.ppf([a / 2, 1 - a / 2], dof * vt.size) / vt.size
                    inside_t.append(lo_t <= vt.mean() <= hi_t)
            lo, hi = stats.chi2.ppf([a / 2, 1 - a / 2], dof * n_runs) / n_runs
            inside = float(np.mean(inside_t)) if inside_t else float("nan")
            rows.append({"quantity": f"a{name}", "n": len(v), "mean": float(np.nanmean(v)),
                         "median": float(np.nanmedian(v)), "chi2_lo": float(lo), "chi2_hi": float(hi),
                         "fraction_inside": inside})
    return rows
