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
"""

from __future__ import annotations

import math

import numpy as np

DEFAULT_ALPHA0 = math.radians(60.0)


def mcewen_relative(cos_i, cos_r, phase, albedo, alpha0: float = DEFAULT_ALPHA0, ls_weight: float = 2.0):
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

    Returns
    -------
    numpy.ndarray
        π times the radiance factor of the lab's McEwen law (same shape as the broadcast inputs).
    """
    cos_i, cos_r, phase, albedo = np.broadcast_arrays(*(np.asarray(x, dtype=np.float64)
                                                        for x in (cos_i, cos_r, phase, albedo)))
    lit = (cos_i > 0.0) & (cos_r > 0.0)
    beta = np.exp(-phase / alpha0)
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
