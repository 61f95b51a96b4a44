"""Method (b): limb scan + ellipse fit, the fitted limb conic turned into the camera-to-body vector.

Description
-----------
The lit limb's points (:mod:`.limb_scan`) are fitted with an ellipse in ideal pixels:

* ``fitter = "direct"``: the direct least-squares ellipse fit of A. Fitzgibbon, M. Pilu and R. B. Fisher, "Direct
  least square fitting of ellipses", IEEE TPAMI 21(5), 1999, doi:10.1109/34.765658 — minimise ``Σ (dᵢᵀa)²`` (dᵢ =
  (x², xy, y², x, y, 1), a the conic's coefficients) subject to ``4ac − b² = 1``, which always gives an ellipse — in
  the numerically stable block form of R. Halíř and J. Flusser ("Numerically stable direct least squares fitting of
  ellipses", WSCG 1998): with ``D₁ = [x², xy, y²]``, ``D₂ = [x, y, 1]``, ``Sᵢⱼ = DᵢᵀDⱼ``, ``T = −S₂₂⁻¹S₁₂ᵀ``, the
  quadratic part ``a₁`` is the eigenvector of ``C₁⁻¹(S₁₁ + S₁₂T)`` with ``4a₁₀a₁₂ − a₁₁² > 0`` and the linear part
  ``a₂ = T a₁`` (19); points are centred and scaled first.
* ``fitter = "opencv"``: ``cv2.fitEllipse``, the baseline.

Points farther than ``reject_sigma`` robust σ (Sampson distance) from the fit are dropped and the fit repeated (twice at
most). The fitted conic ``C`` becomes the cone ``M = KᵀCK`` (eq. 2 of :mod:`renderlab.geometry.conic` inverted) and,
through ``U`` (:mod:`.common`), the cone ``M' = U⁻ᵀ M U⁻¹`` of the unit sphere seen from ``r' = U r``. For an exact limb
``M' ∝ r'r'ᵀ − (r'ᵀr' − 1) I``: one eigenvalue ``λ∥`` along ``r'``, two ``λ⊥ = −(|r'|² − 1) λ∥`` across it, so

    r' = v∥ · √(1 − λ̄⊥/λ∥),   r = U⁻¹ r'                                                                    (20)

(λ̄⊥ the mean of the two — a fitted conic has five degrees of freedom, the body position three; the rest is the fit's
error). The centre is ``camera.project(r)``; the ``limb_*`` fields are the fitted ellipse (ideal pixels); the
covariance is eqs. 17–18 of :mod:`.horizon` at this solution (first order in the edge noise; the fit is not the
maximum-likelihood estimate, so it is optimistic for it).

Tuning
------
======================  ========  ===============================================================================
knob                    default   turn it when
======================  ========  ===============================================================================
``scan``                —         the limb scan (:mod:`.limb_scan`, its own table)
``fitter``              direct    ``opencv``: ``cv2.fitEllipse`` (the baseline)
``reject_sigma``        4.0       outlier gate in robust σ of the Sampson distances; 0: keep all
``edge_sigma_px``       0.05      floor of the edge noise in the covariance (px)
``min_points``          8         fewer limb points: no result (``too_few_points``)
``min_radius_px``       4.0       smaller bodies: no result (``too_small``)
======================  ========  ===============================================================================

Use
---
::

    from estimators.centre_limb import LimbEllipse
    est = LimbEllipse().measure(frame)   # est.limb_centre_s, est.limb_a_px, est.centre_s, est.r_cam_m
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from estimators.centre_limb import common
from estimators.centre_limb.horizon import finish
from estimators.centre_limb.limb_scan import LimbScanOptions, limb_points
from renderlab.geometry.conic import conic_distance, ellipse_params, ellipse_to_conic, pixels_to_cone


@dataclass(frozen=True)
class EllipseOptions:
    """Knobs of :class:`LimbEllipse` (module docstring, Tuning)."""

    scan: LimbScanOptions = field(default_factory=LimbScanOptions)
    fitter: str = "direct"
    reject_sigma: float = 4.0
    edge_sigma_px: float = 0.05
    min_points: int = 8
    min_radius_px: float = 4.0


def fit_ellipse_direct(points: np.ndarray) -> np.ndarray | None:
    """Eq. 19: the conic (3, 3) of the direct least-squares ellipse through ``points`` (n, 2), or None."""
    p = np.asarray(points, float)
    m = p.mean(axis=0)
    sc = float(np.sqrt(np.mean(np.sum((p - m) ** 2, axis=1)))) or 1.0
    x, y = ((p - m) / sc).T
    D1 = np.column_stack([x * x, x * y, y * y])
    D2 = np.column_stack([x, y, np.ones_like(x)])
    S1, S2, S3 = D1.T @ D1, D1.T @ D2, D2.T @ D2
    try:
        T = -np.linalg.solve(S3, S2.T)
    except np.linalg.LinAlgError:
        return None
    Mq = S1 + S2 @ T
    Mq = np.array([Mq[2] / 2.0, -Mq[1], Mq[0] / 2.0])  # C1⁻¹ (S1 + S2 T), C1 = [[0, 0, 2], [0, −1, 0], [2, 0, 0]]
    w, v = np.linalg.eig(Mq)
    v = np.real(v)
    cond = 4 * v[0] * v[2] - v[1] ** 2
    good = np.nonzero(cond > 0)[0]
    if len(good) != 1:
        return None
    a1 = v[:, good[0]]
    A, B, C, D, E, F = np.concatenate([a1, T @ a1])
    Cx = np.array([[A, B / 2, D / 2], [B / 2, C, E / 2], [D / 2, E / 2, F]])
    N = np.array([[1 / sc, 0, -m[0] / sc], [0, 1 / sc, -m[1] / sc], [0, 0, 1.0]])
    return N.T @ Cx @ N


def fit_ellipse_opencv(points: np.ndarray) -> np.ndarray | None:
    """``cv2.fitEllipse`` as a conic (3, 3), or None."""
    import cv2

    if len(points) < 5:
        return None
    (cx, cy), (w, h), ang = cv2.fitEllipse(np.asarray(points, np.float32))
    if not (w > 0 and h > 0):
        return None
    a, b, t = (w / 2, h / 2, np.radians(ang)) if w >= h else (h / 2, w / 2, np.radians(ang) + np.pi / 2)
    return ellipse_to_conic((cx, cy), a, b, t)


def position_from_conic(pred, C: np.ndarray) -> np.ndarray | None:
    """Eq. 20: the camera-frame body centre of a limb conic ``C`` (ideal pixels), or None."""
    Ui = np.linalg.inv(pred.U)
    Mp = Ui.T @ pixels_to_cone(C, pred.K) @ Ui
    lam, vec = np.linalg.eigh(0.5 * (Mp + Mp.T))
    if np.sum(lam > 0) == 2:
        lam, vec = -lam[::-1], vec[:, ::-1]
    if not (lam[2] > 0 and lam[1] < 0):
        return None
    q = 1.0 - 0.5 * (lam[0] + lam[1]) / lam[2]
    rp = vec[:, 2] * np.sqrt(q)
    r = Ui @ rp
    if r[2] < 0:
        r = -r
    return r


class LimbEllipse:
    """Limb scan + ellipse fit (module docstring)."""

    name = "limb_ellipse"

    def __init__(self, options: EllipseOptions = EllipseOptions()):
        if options.fitter not in ("direct", "opencv"):
            raise ValueError(f"fitter must be 'direct' or 'opencv', got {options.fitter!r}")
        self.options = options

    def measure(self, frame) -> common.Estimate:
        """Eqs. 13–14, 19–20 on ``frame`` (attributes in :mod:`.common`)."""
        t0 = time.perf_counter()
        est = self._measure(frame)
        est.t_ms = (time.perf_counter() - t0) * 1e3
        return est

    def _fit(self, u: np.ndarray) -> np.ndarray | None:
        return fit_ellipse_direct(u) if self.options.fitter == "direct" else fit_ellipse_opencv(u)

    def _measure(self, frame) -> common.Estimate:
        o = self.options
        pred, pts, failed = limb_points(frame, o.scan, o.min_radius_px, o.min_points)
        if failed is not None:
            return failed
        keep = np.ones(len(pts.ideal), bool)
        for _ in range(3):
            C = self._fit(pts.ideal[keep])
            if C is None or o.reject_sigma <= 0:
                break
            d = np.abs(conic_distance(C, pts.ideal))
            new = d <= max(o.reject_sigma * 1.4826 * float(np.median(d[keep])), 1e-3)
            if np.array_equal(new, keep) or new.sum() < o.min_points:
                break
            keep = new
        else:
            C = self._fit(pts.ideal[keep])
        ell = None if C is None else ellipse_params(C)
        r = None if ell is None else position_from_conic(pred, C)
        if r is None:
            return common.Estimate(reason=common.FIT_FAILED, limb_points=pts.image,
                                   diagnostics="no ellipse" if ell is None else "no cone of the body")
        est = common.Estimate(limb_points=pts.image[keep], diagnostics=f"points {keep.sum()}/{len(keep)}")
        est.set_ellipse(ell)
        return finish(est, frame, pred, pts.ideal[keep], r, o.edge_sigma_px)
