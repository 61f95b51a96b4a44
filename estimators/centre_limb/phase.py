"""Centre-of-brightness offset of a sphere at phase angle α, in units of its apparent radius.

Seen from afar (orthographic view along −ẑ, Sun ``ŝ = (sin α, 0, cos α)``), a sphere of unit radius lit by a law
``L(μ₀, μ)`` (μ₀ = n·ŝ, μ = n_z) has its brightness centroid displaced toward the Sun's side by

    δ(α) = ∫ x L dA / ∫ L dA,  the integrals over the lit visible disc (μ₀ > 0, μ > 0), dA = μ dΩ.         (5)

Lambert (L ∝ μ₀): ∫ L dA = (2/3)[sin α + (π − α) cos α] (the Lambert phase integral) and
∫ x L dA = (π/8) sin α (1 + cos α), hence the closed form

    δ_L(α) = (3π/16) · sin α (1 + cos α) / (sin α + (π − α) cos α),                                          (6)

0 at full phase, 0.589 at quadrature, → 1 toward new phase: the photocentre displacement of a Lambert sphere,
derived here from eq. 5 (the two integrals in closed form) and checked against scipy's ``dblquad`` of eq. 5 in the
tests (``tests/test_centre_limb_methods.py``). Lommel–Seeliger (L ∝ μ₀/(μ₀ + μ)): :func:`offset` reduces eq. 5 to
one-dimensional integrals (eq. 7 of :func:`quadrature_offset`) evaluated by 64-point Gauss–Legendre quadrature.
"""

from __future__ import annotations

import functools
import math

import numpy as np

LAWS = ("lambert", "lommel_seeliger")


def lambert_offset(alpha) -> np.ndarray:
    """Eq. 6: the Lambert sphere's centroid offset (fraction of the radius) at phase ``alpha`` (rad)."""
    a = np.asarray(alpha, float)
    num = 3 * np.pi / 16 * np.sin(a) * (1 + np.cos(a))
    den = np.sin(a) + (np.pi - a) * np.cos(a)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(a < 1e-12, 0.0, num / den)


@functools.lru_cache(maxsize=8)
def _nodes(n: int) -> tuple[np.ndarray, np.ndarray]:
    return np.polynomial.legendre.leggauss(n)


def quadrature_offset(alpha: float, law: str, n: int = 64) -> float:
    """Eq. 5 by Gauss–Legendre quadrature in coordinates where the lit visible lune is a rectangle (eq. 7).

    With the pole along ŷ (across both the view and the Sun), ``n = (cos b cos l, sin b, cos b sin l)``,
    ``μ = cos b sin l``, ``μ₀ = cos b sin(l + α)``, ``dA = μ dΩ = cos² b sin l db dl`` and the lune is
    ``l ∈ (0, π − α)``, ``b ∈ (−π/2, π/2)``. Both laws are ``cos^k b · g(l)`` (Lambert: k = 1, g = sin(l + α);
    Lommel–Seeliger: k = 0, g = sin(l + α)/(sin(l + α) + sin l)), so the b integrals are closed:

        δ = [∫cos^(k+3) b db / ∫cos^(k+2) b db] · ∫ g sin l cos l dl / ∫ g sin l dl.                       (7)
    """
    if alpha >= math.pi:
        return 1.0
    x, w = _nodes(n)
    span = math.pi - alpha
    lon = (x + 1) * span / 2
    wl = w * span / 2
    sa = np.sin(lon + alpha)
    if law == "lambert":
        k, g = 1, sa
    else:
        k, g = 0, sa / (sa + np.sin(lon))
    cos_int = {2: math.pi / 2, 3: 4.0 / 3.0, 4: 3 * math.pi / 8}  # ∫ cos^m b db over (−π/2, π/2)
    flux = np.sum(wl * g * np.sin(lon))
    return float(cos_int[k + 3] / cos_int[k + 2] * np.sum(wl * g * np.sin(lon) * np.cos(lon)) / flux)


def offset(alpha: float, law: str) -> float:
    """δ(α) of eq. 5 for ``law`` (``lambert``: eq. 6; ``lommel_seeliger``: eq. 7)."""
    if law == "lambert":
        return float(lambert_offset(alpha))
    if law not in LAWS:
        raise ValueError(f"phase correction law must be one of {', '.join(LAWS)}, got {law!r}")
    return quadrature_offset(float(alpha), law)
