r"""The onboard photometric model: McEwen's lunar-Lambert law as Retina uses it.

Retina (Wright et al.) illuminates each ray-traced, unshadowed maplet point with eq. 5

.. math:: I_k = a_k\left[(1-\beta)\cos i_k + c\,\beta\,\frac{\cos i_k}{\cos i_k + \cos r_k}\right],
          \qquad \beta = e^{-\alpha/\alpha_0}

with :math:`\cos i_k = \hat n_k^T \hat s_M` (eq. 6), :math:`\cos r_k = \hat n_k^T \hat r_M` (eq. 7) and the
phase angle :math:`\alpha = \cos^{-1}(\hat s_M^T \hat r_M)` (eq. 8). ``c`` (``ls_weight``) is 1 in the paper's
eq. 5 and 2 in McEwen's normalisation (the Lommel-Seeliger part equals Lambert at normal incidence and
emission). Correlation (eq. 9) is invariant to a global gain, so the 1/π and the solar irradiance are
dropped here: the result is a *relative* brightness.

Estimators may not import the lab's photometry; this is an independent re-implementation (the tests
compare it with :func:`renderlab.photometry.mcewen` as the oracle).

Fitted weight L(α). Retina's β = exp(−α/α0) is one choice of McEwen's (1991) lunar-Lambert weight L(α);
McEwen obtained L(α) by fitting the lunar-Lambert form, eq. 5 with β → L(α) and c = 2, to a physical law
(Hapke) over incidence and emission at each phase. :func:`fit_lunar_lambert_L` does that least-squares
fit for any reflectance function the ground knows (the body's catalogued law), tabulated over phase;
the kernels interpolate the table (``L_table``; an empty table means β = exp(−α/α0)).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

DEFAULT_ALPHA0 = math.radians(60.0)
L_TABLE_SIZE = 181  # L(α) tabulated every 1° over [0, π]


def beta_of_phase(phase, alpha0: float = DEFAULT_ALPHA0, L_table=None):
    """The lunar-Lambert weight: ``exp(−α/α0)`` (eq. 5), or L(α) interpolated linearly in a table over
    [0, π] (``L_table`` with ≥ 2 entries, e.g. from :func:`fit_lunar_lambert_L`)."""
    phase = np.asarray(phase, dtype=np.float64)
    if L_table is None or len(L_table) < 2:
        return np.exp(-phase / alpha0)
    L = np.asarray(L_table, dtype=np.float64)
    return np.interp(np.clip(phase, 0.0, math.pi), np.linspace(0.0, math.pi, len(L)), L)


def mcewen_relative(cos_i, cos_r, phase, albedo, alpha0: float = DEFAULT_ALPHA0, ls_weight: float = 2.0,
                    L_table=None):
    """Relative McEwen brightness (eq. 5), 0 where ``cos_i <= 0`` or ``cos_r <= 0``.

    Parameters
    ----------
    cos_i, cos_r : array_like
        Cosines of the incidence (eq. 6) and emission/reflectance (eq. 7) angles.
    phase : array_like
        Phase angle α (eq. 8), rad.
    albedo : array_like
        Relative albedo a_k.
    alpha0 : float
        β = exp(−α/α0) decay constant, rad.
    ls_weight : float
        Weight c of the Lommel-Seeliger term (2: McEwen; 1: eq. 5 literally).
    L_table : array_like, optional
        Tabulated L(α) over [0, π] replacing exp(−α/α0) (see :func:`beta_of_phase`).

    Returns
    -------
    numpy.ndarray
        π times the radiance factor of the lab's McEwen law (same shape as the broadcast inputs).
    """
    cos_i, cos_r, phase, albedo = np.broadcast_arrays(*(np.asarray(x, dtype=np.float64)
                                                        for x in (cos_i, cos_r, phase, albedo)))
    lit = (cos_i > 0.0) & (cos_r > 0.0)
    beta = beta_of_phase(phase, alpha0, L_table)
    den = np.where(lit, cos_i + cos_r, 1.0)
    out = albedo * ((1.0 - beta) * cos_i + ls_weight * beta * cos_i / den)
    return np.where(lit, out, 0.0)


try:  # the scalar kernel for the ray tracer (numba); same formula as mcewen_relative
    from numba import njit
except ImportError:  # pragma: no cover - numba is a dependency
    njit = None


def _mcewen_scalar_py(cos_i, cos_r, phase, albedo, alpha0, ls_weight):
    if cos_i <= 0.0 or cos_r <= 0.0:
        return 0.0
    beta = math.exp(-phase / alpha0)
    return albedo * ((1.0 - beta) * cos_i + ls_weight * beta * cos_i / (cos_i + cos_r))


mcewen_scalar = njit(cache=True)(_mcewen_scalar_py) if njit else _mcewen_scalar_py


def _beta_scalar_py(phase, alpha0, L_table):
    m = L_table.shape[0]
    if m < 2:
        return math.exp(-phase / alpha0)
    x = min(max(phase, 0.0), math.pi) / math.pi * (m - 1)
    k = min(int(x), m - 2)
    f = x - k
    return (1.0 - f) * L_table[k] + f * L_table[k + 1]


def _mcewen_beta_scalar_py(cos_i, cos_r, beta, albedo, ls_weight):
    if cos_i <= 0.0 or cos_r <= 0.0:
        return 0.0
    return albedo * ((1.0 - beta) * cos_i + ls_weight * beta * cos_i / (cos_i + cos_r))


beta_scalar = njit(cache=True)(_beta_scalar_py) if njit else _beta_scalar_py
mcewen_beta_scalar = njit(cache=True)(_mcewen_beta_scalar_py) if njit else _mcewen_beta_scalar_py


@dataclass(frozen=True)
class LunarLambertFit:
    """L(α) fitted to a reflectance law (:func:`fit_lunar_lambert_L`).

    Attributes
    ----------
    phase_rad : numpy.ndarray
        The phase angles of the fit, rad.
    L : numpy.ndarray
        Fitted lunar-Lambert weight at each phase.
    A : numpy.ndarray
        Fitted gain at each phase (units of the reflectance; Retina ignores it, eq. 9 is gain-invariant).
    rms_rel : numpy.ndarray
        RMS residual of the fit divided by the mean reflectance, at each phase.
    """

    phase_rad: np.ndarray
    L: np.ndarray
    A: np.ndarray
    rms_rel: np.ndarray


def fit_lunar_lambert_L(reflectance, phase_rad=None, incidence_max_deg: float = 80.0,
                        emission_max_deg: float = 70.0, step_deg: float = 2.0,
                        ls_weight: float = 2.0) -> LunarLambertFit:
    r"""Least-squares lunar-Lambert weight L(α) of a reflectance law (McEwen 1991).

    At each phase α the model :math:`r \approx A\,[(1-L)\mu_0 + c\,L\,\mu_0/(\mu_0+\mu)]` (eq. 5 with
    β → L(α)) is linear in :math:`a_1 = A(1-L)` and :math:`a_2 = AL`; it is fitted over a regular grid of
    incidence i ≤ ``incidence_max_deg`` and emission e ≤ ``emission_max_deg`` restricted to the
    geometries that exist at that phase (|i − e| ≤ α ≤ i + e), and :math:`L = a_2/(a_1 + a_2)`.

    Parameters
    ----------
    reflectance : callable
        ``reflectance(mu0, mu, phase)`` → radiance factor (any scale), vectorised over numpy arrays;
        e.g. the body's catalogued Hapke law at its mean single-scattering albedo.
    phase_rad : array_like, optional
        Phases at which to fit (default: :data:`L_TABLE_SIZE` points over [0, π]).
    incidence_max_deg, emission_max_deg, step_deg : float
        The (i, e) grid of the fit, degrees.
    ls_weight : float
        c of eq. 5 (2: McEwen).

    Returns
    -------
    LunarLambertFit
        Phases with fewer than 3 feasible geometries (α beyond i_max + e_max) copy the nearest fitted L.
    """
    ph = np.linspace(0.0, math.pi, L_TABLE_SIZE) if phase_rad is None else np.asarray(phase_rad, float).ravel()
    ig = np.radians(np.arange(0.0, incidence_max_deg + 1e-9, step_deg))
    eg = np.radians(np.arange(0.0, emission_max_deg + 1e-9, step_deg))
    I, E = (a.ravel() for a in np.meshgrid(ig, eg, indexing="ij"))
    L, A, rms = np.full(len(ph), np.nan), np.full(len(ph), np.nan), np.full(len(ph), np.nan)
    for k, a in enumerate(ph):
        ok = (np.abs(I - E) <= a + 1e-12) & (a <= I + E + 1e-12)
        if ok.sum() < 3:
            continue
        mu0, mu = np.cos(I[ok]), np.cos(E[ok])
        r = np.asarray(reflectance(mu0, mu, np.full(mu0.shape, a)), float)
        X = np.column_stack([mu0, ls_weight * mu0 / (mu0 + mu)])
        (a1, a2), *_ = np.linalg.lstsq(X, r, rcond=None)
        L[k], A[k] = a2 / (a1 + a2), a1 + a2
        rms[k] = float(np.sqrt(np.mean((X @ np.array([a1, a2]) - r) ** 2)) / max(np.mean(np.abs(r)), 1e-300))
    good = np.flatnonzero(np.isfinite(L))
    if good.size == 0:
        raise ValueError("no phase angle has enough feasible incidence/emission geometries to fit L")
    near = good[np.abs(good[None, :] - np.arange(len(ph))[:, None]).argmin(axis=1)]
    return LunarLambertFit(ph, L[near], A[near], rms[near])
