r"""Re-centred sub-pixel peak: move the template by the current sub-pixel estimate and refit at zero offset.

Description
-----------
Every 3-point or 3×3 peak fit of :mod:`estimators.landmarks.peaks` is exact at integer shifts and wrong in between when the
correlation surface (Retina eq. 9) does not have the shape the fit assumes (pixel locking). Sampling the
surface *around the estimate* instead of around the integer maximum removes most of it: with the estimate
δ = n + φ (n integer, |φ| ≤ ½), the template I_p is moved by φ, I_p'(x) = I_p(x − φ) (cubic B-spline
interpolation of the noise-free template, its footprint mean outside the footprint, the footprint eroded by one
pixel on every side), eq. 9 is evaluated at the nine integer shifts n + (−1, 0, 1)², and the
finder's offset from their centre, ε, gives δ ← n + φ + ε. The residual ε is the finder's bias at a near-zero
offset, where every symmetric fit is exact, so each pass shrinks the error by the slope of the finder's locking
curve there (measured: ``benchmarks/bench_retina_peak_step.py``). The image is not resampled, so its noise
stays white and the registration Cramér–Rao bound applies unchanged.

Tuning
------
``iterations`` (passes; 0 = the finder alone), the finder (``gaussian_2d`` by default), ``min_pixels``
(overlap required at each of the nine shifts; a pass that fails keeps the previous estimate).

Use
---
::

    ds, dl = recentred_shift(image, tpl.image, tpl.valid, tpl.s0, tpl.l0, peak.ds, peak.dl, "gaussian_2d", 2)

References
----------
C. A. Wright et al., "Relative Terrain Imaging Navigation (RETINA) Tool for the Asteroid Redirect Robotic Mission
(ARRM)", NASA GSFC, 2016 (eq. 9; "Peak Finding").
"""

from __future__ import annotations

import numpy as np

from estimators.landmarks.correlation import correlation_surface_direct
from estimators.landmarks.peaks import FINDERS


def moved_template(template: np.ndarray, valid: np.ndarray, phase_sl) -> tuple[np.ndarray, np.ndarray]:
    """``(T', V')``: the template moved by (φs, φl) px (|φ| ≤ ½), T'(x) = T(x − φ) by cubic B-spline
    interpolation (exact for cubic polynomials; ``scipy.ndimage.shift``, order 3) of the footprint (its mean
    outside it), and the footprint eroded by one pixel on every side (whatever the sign of φ, so the pixel
    set does not jump as φ crosses zero)."""
    from scipy.ndimage import shift

    t = np.asarray(template, float)
    v = np.asarray(valid, bool)
    moved = shift(np.where(v, t, float(t[v].mean())), (phase_sl[1], phase_sl[0]), order=3, mode="nearest")
    vv = v.copy()
    vv[[0, -1], :] = False
    vv[:, [0, -1]] = False
    vv[1:-1, 1:-1] &= v[:-2, 1:-1] & v[2:, 1:-1] & v[1:-1, :-2] & v[1:-1, 2:]
    return moved, vv


def recentred_shift(image, template, valid, s0: int, l0: int, ds: float, dl: float, finder: str = "gaussian_2d",
                    iterations: int = 2, image_valid=None, min_pixels: int = 16) -> tuple[float, float]:
    """The shift (Δs, Δl) after ``iterations`` re-centred passes from (``ds``, ``dl``) (module docstring)."""
    fit = FINDERS[finder]
    for _ in range(int(iterations)):
        n = (int(np.round(ds)), int(np.round(dl)))
        phase = (ds - n[0], dl - n[1])
        T, V = moved_template(template, valid, phase)
        if V.sum() < min_pixels:
            break
        C, _ = correlation_surface_direct(image, T, V, s0 + n[0], l0 + n[1], 1, image_valid, min_pixels)
        if not np.all(np.isfinite(C)):
            break
        e = fit(C, 1, 1)
        ds, dl = n[0] + phase[0] + min(max(float(e[0]), -1.0), 1.0), n[1] + phase[1] + min(max(float(e[1]), -1.0), 1.0)
    return float(ds), float(dl)
