"""Per-pixel, counter-based sensor noise: every random variate of a pixel is a pure function of
(frame key, pixel index, draw number).

**Uniforms.** Philox4x64-10 (J. K. Salmon, M. A. Moraes, R. O. Dror, D. E. Shaw, "Parallel random numbers: as
easy as 1, 2, 3", SC '11, doi:10.1145/2063384.2063405), the same function as Random123's ``philox4x64_10`` and
numpy's :class:`numpy.random.Philox` bit generator (the tests check it against both). One block maps a 256-bit
counter and a 128-bit key to four 64-bit words. Pixel ``i`` (row-major index in the (H, W) image) draws
uniforms ``U_i(0), U_i(1), …``: draw ``d`` is word ``d mod 4`` of the block with counter ``(i, d // 4, 0, 0)``
under the frame key ``(k0, k1)``, turned into a double in (0, 1) as ``((w >> 11) + 1/2) · 2⁻⁵³`` (never 0 or 1).

**Draw layout of a pixel.** Draws 0 and 1: the read noise, Box–Muller ``z = sqrt(−2 ln U₀) cos(2π U₁)``
(G. E. P. Box, M. E. Muller, Ann. Math. Statist. 29(2), 610, 1958, doi:10.1214/aoms/1177706645). Draws
``2 + 2k`` and ``3 + 2k``: attempt ``k`` (k = 0, 1, …) of the shot-noise Poisson draw, so a pixel's read noise does
not depend on how many attempts its Poisson draw took, and the common case (no rejection) costs one block.

**Poisson(μ).**

* ``μ < 10``: inversion by sequential search on ``U_i(2)`` alone (the CDF summed from ``e^{−μ}`` with the
  recurrence ``p_k = p_{k−1} μ / k``; L. Devroye, *Non-Uniform Random Variate Generation*, Springer 1986, X.3.3,
  doi:10.1007/978-1-4613-8643-8). The search stops if the summed CDF stops growing in floating point (a draw
  within about 1e-16 of 1), returning the k reached there.
* ``μ ≥ 10``: Hörmann's PTRS transformed rejection with its squeeze, as published (W. Hörmann, "The transformed
  rejection method for generating Poisson random variables", Insurance: Mathematics and Economics 12(1), 39, 1993,
  doi:10.1016/0167-6687(93)90997-4), for every μ up to the sensor's cap of 1e15: no normal approximation. Two
  changes keep it exact in double precision at large μ: the candidate is ``⌊μ⌋ + ⌊(2a/u_s + b) U + (μ − ⌊μ⌋) +
  0.43⌋`` (the same integer as Hörmann's ``⌊(2a/u_s + b) U + μ + 0.43⌋`` without rounding the sum at the
  magnitude of μ), and the log-pmf of the acceptance test is Loader's saddle-point form
  ``log p(k) = −stirlerr(k) − bd0(k, μ) − ½ log(2πk)`` (C. Loader, "Fast and accurate computation of binomial
  probabilities", 2000; as in R's ``dpois``), whose terms are O(1) where ``−μ + k log μ − lgamma(k + 1)``
  cancels terms of size ``μ log μ`` (about 3.5e16 at μ = 1e15, i.e. errors of several units in the log).

The kernels are compiled with numba on first use (cached on disk); :mod:`renderlab.sensor.model` imports this module
only when it draws noise, so importing the sensor model stays light.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from llvmlite import ir
from numba.extending import intrinsic

NOISE_STREAMS = ("per_pixel", "sequential")
"""Values of ``SensorOptions.noise_stream``: the per-pixel counter-based stream (default) and the former order."""
PTRS_MIN_MEAN = 10.0
"""Means at or above this use PTRS; below it, inversion (Hörmann's recommended range for PTRS is μ ≥ 10)."""

_U = np.uint64
_M0, _M1 = _U(0xD2E7470EE14C6C93), _U(0xCA5A826395121157)  # Philox4x64 multipliers
_W0, _W1 = _U(0x9E3779B97F4A7C15), _U(0xBB67AE8584CAA73B)  # Weyl key increments (golden ratio, sqrt(3) - 1)
_S11 = _U(11)
_TWO_M53 = 2.0 ** -53
_LN_SQRT_2PI = 0.5 * math.log(2.0 * math.pi)
_S0, _S1, _S2, _S3, _S4 = 1.0 / 12, 1.0 / 360, 1.0 / 1260, 1.0 / 1680, 1.0 / 1188  # Stirling series


@intrinsic
def _mulhi64(typingctx, a, b):  # pragma: no cover - numba
    """High 64-bit word of the 128-bit product ``a · b`` of two uint64: one widening multiply in LLVM IR (numba has
    no 128-bit integer type; a product of 32-bit halves takes four multiplies)."""
    sig = numba.types.uint64(numba.types.uint64, numba.types.uint64)

    def codegen(context, builder, signature, args):
        wide = ir.IntType(128)
        prod = builder.mul(builder.zext(args[0], wide), builder.zext(args[1], wide))
        return builder.trunc(builder.lshr(prod, ir.Constant(wide, 64)), ir.IntType(64))

    return sig, codegen


@numba.njit(cache=True, inline="always")
def _mulhilo(a, b):  # pragma: no cover - numba
    """High and low 64-bit words of the 128-bit product ``a · b``."""
    return _mulhi64(a, b), a * b


@numba.njit(cache=True)
def _philox_block(c0, c1, c2, c3, k0, k1):  # pragma: no cover - numba
    """Philox4x64-10 of counter ``(c0, c1, c2, c3)`` under key ``(k0, k1)`` (all uint64)."""
    for r in range(10):
        if r > 0:
            k0 += _W0
            k1 += _W1
        hi0, lo0 = _mulhilo(_M0, c0)
        hi1, lo1 = _mulhilo(_M1, c2)
        c0, c1, c2, c3 = hi1 ^ c1 ^ k0, lo1, hi0 ^ c3 ^ k1, lo0
    return c0, c1, c2, c3


@numba.njit(cache=True, inline="always")
def _unit(w):  # pragma: no cover - numba
    """A 64-bit word as a double in (0, 1): its top 53 bits, centred in their cell."""
    return (float(w >> _S11) + 0.5) * _TWO_M53


@numba.njit(cache=True)
def _stirlerr(n):  # pragma: no cover - numba
    """``lgamma(n + 1) − (n + ½) log n + n − log sqrt(2π)`` for an integer n ≥ 1 (Loader 2000)."""
    if n <= 15.0:
        return math.lgamma(n + 1.0) - (n + 0.5) * math.log(n) + n - _LN_SQRT_2PI
    nn = n * n
    if n > 500.0:
        return (_S0 - _S1 / nn) / n
    if n > 80.0:
        return (_S0 - (_S1 - _S2 / nn) / nn) / n
    if n > 35.0:
        return (_S0 - (_S1 - (_S2 - _S3 / nn) / nn) / nn) / n
    return (_S0 - (_S1 - (_S2 - (_S3 - _S4 / nn) / nn) / nn) / nn) / n


@numba.njit(cache=True)
def _bd0(x, m):  # pragma: no cover - numba
    """``x log(x/m) + m − x`` without cancellation near ``x = m`` (Loader 2000: series in ``(x−m)/(x+m)``)."""
    d = x - m
    if abs(d) < 0.1 * (x + m):
        v = d / (x + m)
        s = d * v
        ej = 2.0 * x * v
        v2 = v * v
        for j in range(1, 1000):
            ej *= v2
            s1 = s + ej / (2 * j + 1)
            if s1 == s:
                return s1
            s = s1
        return s
    return x * math.log(x / m) + m - x


@numba.njit(cache=True)
def _log_pmf(k, m):  # pragma: no cover - numba
    """``log P(K = k)`` for K ~ Poisson(m), k a non-negative integer (float), m > 0."""
    if k < 1.0:
        return -m
    return -_stirlerr(k) - _bd0(k, m) - 0.5 * math.log(2.0 * math.pi * k)


@numba.njit(cache=True)
def _poisson_inversion(m, u):  # pragma: no cover - numba
    """Poisson(m) by sequential search of the CDF for the uniform ``u``."""
    p = math.exp(-m)
    f = p
    k = 0.0
    while u > f:
        k += 1.0
        p *= m / k
        if f + p == f:  # the summed CDF has stopped growing: u is within rounding of 1
            break
        f += p
    return k


@numba.njit(cache=True)
def _poisson_ptrs(m, i, k0, k1, w2, w3):  # pragma: no cover - numba
    """Poisson(m), m ≥ 10, by PTRS; attempt 0 uses the words ``w2, w3`` (draws 2, 3) of pixel ``i``'s block 0,
    attempt k the draws ``2 + 2k, 3 + 2k``."""
    b = 0.931 + 2.53 * math.sqrt(m)
    a = -0.059 + 0.02483 * b
    log_inv_alpha = math.log(1.1239 + 1.1328 / (b - 3.4))
    vr = 0.9277 - 3.6224 / (b - 2.0)
    m_int = math.floor(m)
    m_frac = m - m_int
    pi = _U(i)
    zero = _U(0)
    attempt = 0
    while True:
        if attempt % 2 == 1:  # draws 2 + 2k, 3 + 2k are words 0, 1 of block (k + 1) / 2 ...
            w0, w1, w2, w3 = _philox_block(pi, _U((attempt + 1) // 2), zero, zero, k0, k1)
            big_u, v = _unit(w0) - 0.5, _unit(w1)
        else:  # ... or words 2, 3 of block k / 2 (already drawn)
            big_u, v = _unit(w2) - 0.5, _unit(w3)
        attempt += 1
        us = 0.5 - abs(big_u)
        k = m_int + math.floor((2.0 * a / us + b) * big_u + m_frac + 0.43)
        if us >= 0.07 and v <= vr:
            return k
        if k < 0.0 or (us < 0.013 and v > us):
            continue
        if math.log(v) + log_inv_alpha - math.log(a / (us * us) + b) <= _log_pmf(k, m):
            return k


@numba.njit(cache=True, parallel=True)
def _electrons_kernel(mu, read_noise_e, k0, k1, out):  # pragma: no cover - numba
    """``out[i] = Poisson(mu[i]) + read_noise_e · z_i`` with pixel i's counter-based draws (pixels in parallel:
    each depends on its own counters only, so the result does not depend on the thread count)."""
    zero = _U(0)
    two_pi = 2.0 * math.pi
    for i in numba.prange(mu.size):
        w0, w1, w2, w3 = _philox_block(_U(i), zero, zero, zero, k0, k1)
        z = math.sqrt(-2.0 * math.log(_unit(w0))) * math.cos(two_pi * _unit(w1))
        m = mu[i]
        if m < PTRS_MIN_MEAN:
            n = _poisson_inversion(m, _unit(w2))
        else:
            n = _poisson_ptrs(m, i, k0, k1, w2, w3)
        out[i] = n + read_noise_e * z


@numba.njit(cache=True)
def _philox_rows(counters, k0, k1, out):  # pragma: no cover - numba
    for r in range(counters.shape[0]):
        out[r, 0], out[r, 1], out[r, 2], out[r, 3] = _philox_block(counters[r, 0], counters[r, 1], counters[r, 2],
                                                                   counters[r, 3], k0, k1)


def philox4x64(counters, key) -> np.ndarray:
    """Philox4x64-10 blocks: the generator under the per-pixel noise.

    Parameters
    ----------
    counters : array_like of uint64, shape (N, 4)
        256-bit counters, least significant word first.
    key : array_like of uint64, shape (2,)
        128-bit key.

    Returns
    -------
    numpy.ndarray
        uint64 (N, 4): the four output words of each block.
    """
    c = np.ascontiguousarray(np.asarray(counters, dtype=np.uint64).reshape(-1, 4))
    k = np.asarray(key, dtype=np.uint64).reshape(2)
    out = np.empty_like(c)
    _philox_rows(c, k[0], k[1], out)
    return out


def frame_key(rng) -> np.ndarray:
    """The 128-bit frame key of the per-pixel stream, ``rng.integers(0, 2**64, size=2, dtype=uint64)``.

    ``rng`` is a :class:`numpy.random.Generator` (advanced by two 64-bit draws), or a
    :class:`numpy.random.SeedSequence` or non-negative int, which count as ``numpy.random.default_rng(rng)``.
    """
    return as_generator(rng).integers(0, 2 ** 64, size=2, dtype=np.uint64)


def as_generator(rng) -> np.random.Generator:
    """``rng`` itself for a Generator; ``numpy.random.default_rng(rng)`` for a SeedSequence or an int ≥ 0."""
    if isinstance(rng, np.random.Generator):
        return rng
    if isinstance(rng, np.random.SeedSequence) or (isinstance(rng, (int, np.integer)) and not isinstance(rng, bool)
                                                   and rng >= 0):
        return np.random.default_rng(rng)
    raise TypeError(f"rng must be a numpy.random.Generator, SeedSequence or int >= 0, got {rng!r}")


def per_pixel_electrons(mu: np.ndarray, read_noise_e: float, key) -> np.ndarray:
    """Shot plus read noise from the per-pixel counter-based stream.

    Parameters
    ----------
    mu : numpy.ndarray
        Mean electrons per pixel (finite, >= 0, at most 1e15); any shape, indexed in C order.
    read_noise_e : float
        Read noise standard deviation (electrons), >= 0.
    key : array_like of uint64, shape (2,)
        The frame key (:func:`frame_key`).

    Returns
    -------
    numpy.ndarray
        float64, the shape of ``mu``: ``Poisson(mu) + read_noise_e · N(0, 1)``, pixel i from its own draws.
    """
    m = np.ascontiguousarray(mu, dtype=np.float64)
    k = np.asarray(key, dtype=np.uint64).reshape(2)
    out = np.empty_like(m)
    _electrons_kernel(m.reshape(-1), float(read_noise_e), k[0], k[1], out.reshape(-1))
    return out


def draw_electrons(mu: np.ndarray, read_noise_e: float, stream: str, rng) -> np.ndarray:
    """Noisy electrons (shot then read noise) for means ``mu`` by the chosen stream.

    ``"per_pixel"``: :func:`per_pixel_electrons` under :func:`frame_key` of ``rng``. ``"sequential"``: the former
    draw order, ``rng.poisson(mu)`` over the image then ``rng.normal(0, read_noise_e)`` over the image (bit for
    bit what the sensor drew before the per-pixel stream).
    """
    if stream == "sequential":
        rng = as_generator(rng)
        electrons = rng.poisson(mu).astype(np.float64)
        electrons += rng.normal(0.0, float(read_noise_e), size=mu.shape)
        return electrons
    return per_pixel_electrons(mu, read_noise_e, frame_key(rng))
