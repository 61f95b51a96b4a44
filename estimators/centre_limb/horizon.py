"""Method (c): Christian's non-iterative horizon-based OpNav — the camera-to-body vector from limb points.

Description
-----------
J. A. Christian and S. B. Robinson, "Noniterative horizon-based optical navigation by Cholesky factorization",
J. Guidance, Control, and Dynamics 39(12), 2016, doi:10.2514/1.G000539; the limb geometry as in J. A. Christian,
"Accurate planetary limb localization for image-based spacecraft navigation", J. Spacecraft Rockets 54(3), 2017,
doi:10.2514/1.A33692. With the a-priori attitude, ``U = diag(1/a, 1/b, 1/c) R_pᵀ R_body_from_cam`` maps the camera
frame onto the space where the body is the unit sphere (:mod:`.common`). There, the rays to the limb points,
``s̄ᵢ = U xᵢ / |U xᵢ|`` (xᵢ the unprojected limb points), graze the unit sphere centred at ``r' = U r``: the angle
between ``s̄ᵢ`` and ``r'`` is the cone half-angle θ with ``sin θ = 1/|r'|``, so ``s̄ᵢᵀ r' = |r'| cos θ = √(|r'|² − 1)``,
linear in

    n = r' / √(r'ᵀr' − 1):   s̄ᵢᵀ n = 1,  i = 1 … m   (H n = 1),                                            (15)

solved in least squares through the Cholesky factor of ``HᵀH`` (the normal equations), no iteration. Then

    r' = n / √(nᵀn − 1),   r = U⁻¹ r'   (camera frame, m),   range |r|, centre = camera.project(r).          (16)

Covariance (first order): the residual of point i moves by ``gᵢ·δuᵢ`` for a pixel error δuᵢ (``gᵢ`` = ∂(s̄ᵢᵀn)/∂u,
by differences); with the edge noise σ (``edge_sigma_px``, or the a-posteriori ``σ̂² = Σ εᵢ²/|gᵢ|² / (m − 3)`` when
larger), ``P_n = (HᵀH)⁻¹ Hᵀ Σ H (HᵀH)⁻¹`` with ``Σ = diag(σ²|gᵢ|²)`` (17); ``P_r' = J P_n Jᵀ`` with
``J = (nᵀn − 1)^(−1/2) [I − n nᵀ/(nᵀn − 1)]`` (18); ``P_r = U⁻¹ P_r' U⁻ᵀ``; the centre's in px through the camera's
Jacobian. Points farther than ``reject_sigma`` robust σ from the solution are dropped and the solve repeated
(twice at most): craters, a cusp or a stray edge.

Tuning
------
======================  ========  ===============================================================================
knob                    default   turn it when
======================  ========  ===============================================================================
``scan``                —         the limb scan (:mod:`.limb_scan`, its own table)
``edge_sigma_px``       0.05      floor of the edge noise in eq. 17 (px)
``reject_sigma``        4.0       outlier gate, robust σ of the residuals (px); 0: keep all
``min_points``          8         fewer limb points: no result (``too_few_points``)
``min_radius_px``       4.0       smaller bodies: no result (``too_small``); use the centroid
======================  ========  ===============================================================================

Use
---
::

    from estimators.centre_limb import HorizonOpNav
    est = HorizonOpNav().measure(frame)      # est.r_cam_m, est.cov_r_cam_m2, est.centre_s, est.limb_points
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from estimators.centre_limb import common
from estimators.centre_limb.limb_scan import LimbScanOptions, limb_points
from renderlab.geometry.conic import cone_to_pixels, ellipse_params, limb_cone


@dataclass(frozen=True)
class HorizonOptions:
    """Knobs of :class:`HorizonOpNav` (module docstring, Tuning)."""

    scan: LimbScanOptions = field(default_factory=LimbScanOptions)
    edge_sigma_px: float = 0.05
    reject_sigma: float = 4.0
    min_points: int = 8
    min_radius_px: float = 4.0


def sphere_rays(pred, u: np.ndarray) -> np.ndarray:
    """``s̄ᵢ`` of eq. 15: ideal pixels (m, 2) → unit rays in the unit-sphere space."""
    x = np.linalg.solve(pred.K, np.column_stack([u, np.ones(len(u))]).T).T
    s = x @ pred.U.T
    return s / np.linalg.norm(s, axis=1, keepdims=True)


def solve_n(S: np.ndarray) -> np.ndarray | None:
    """Eq. 15: least-squares ``n`` of ``S n = 1`` through the Cholesky factor of ``SᵀS`` (None when singular)."""
    from scipy.linalg import LinAlgError, cho_factor, cho_solve

    try:
        return cho_solve(cho_factor(S.T @ S), S.T @ np.ones(len(S)))
    except (LinAlgError, ValueError):
        return None


def residual_gradients(pred, u: np.ndarray, n: np.ndarray, h: float = 1e-3) -> tuple[np.ndarray, np.ndarray]:
    """(εᵢ = s̄ᵢᵀn − 1, |gᵢ| = |∂εᵢ/∂u| by central differences) of the ideal-pixel points ``u``."""
    eps = sphere_rays(pred, u) @ n - 1.0
    g = np.empty((len(u), 2))
    for k in range(2):
        du = np.zeros(2)
        du[k] = h
        g[:, k] = (sphere_rays(pred, u + du) @ n - sphere_rays(pred, u - du) @ n) / (2 * h)
    return eps, np.linalg.norm(g, axis=1)


def position_covariance(pred, u: np.ndarray, n: np.ndarray, floor_px: float) -> tuple[np.ndarray, float]:
    """(P_r (3, 3) m², edge σ px) of eqs. 17–18 for the solution ``n`` and its points ``u``."""
    S = sphere_rays(pred, u)
    eps, g = residual_gradients(pred, u, n)
    m = len(u)
    sig2 = max(floor_px**2, float(np.sum((eps / g) ** 2)) / max(m - 3, 1))
    N = np.linalg.inv(S.T @ S)
    Pn = N @ (S.T * (sig2 * g**2)) @ S @ N
    q = float(n @ n) - 1.0
    J = (np.eye(3) - np.outer(n, n) / q) / np.sqrt(q)
    Ui = np.linalg.inv(pred.U)
    return Ui @ J @ Pn @ J.T @ Ui.T, float(np.sqrt(sig2))


def n_from_r(pred, r_cam: np.ndarray) -> np.ndarray | None:
    """Inverse of eq. 16: ``n`` of a camera-frame centre (None inside the body)."""
    rp = pred.U @ r_cam
    q = float(rp @ rp) - 1.0
    return rp / np.sqrt(q) if q > 0 else None


def r_from_n(pred, n: np.ndarray) -> np.ndarray | None:
    """Eq. 16: the camera-frame centre of ``n`` (None when ``nᵀn ≤ 1`` or behind the camera)."""
    q = float(n @ n) - 1.0
    if not q > 0:
        return None
    r = np.linalg.solve(pred.U, n / np.sqrt(q))
    return r if r[2] > 0 else None


def finish(est: common.Estimate, frame, pred, u: np.ndarray, r_cam: np.ndarray, floor_px: float) -> common.Estimate:
    """Fill centre, range vector and covariances of ``est`` from a solved ``r_cam`` and its points ``u``."""
    n = n_from_r(pred, r_cam)
    cov_r, sigma = position_covariance(pred, u, n, floor_px)
    sl = frame.camera.project(r_cam)
    est.centre_s, est.centre_l = float(sl[0]), float(sl[1])
    est.r_cam_m, est.cov_r_cam_m2 = r_cam, cov_r
    est.cov_centre_px2 = common.centre_covariance(frame.camera, r_cam, cov_r)
    est.extra["edge_sigma_px"] = sigma
    return est


def inliers(pred, u: np.ndarray, r_cam: np.ndarray, keep: np.ndarray, reject_sigma: float) -> np.ndarray:
    """Points within ``reject_sigma`` robust σ (of the kept points' residuals, px) of the solution ``r_cam``."""
    eps, g = residual_gradients(pred, u, n_from_r(pred, r_cam))
    res = np.abs(eps / g)
    return res <= max(reject_sigma * 1.4826 * float(np.median(res[keep])), 1e-3)


class HorizonOpNav:
    """Christian–Robinson horizon-based OpNav (module docstring)."""

    name = "horizon_opnav"

    def __init__(self, options: HorizonOptions = HorizonOptions()):
        self.options = options

    def measure(self, frame) -> common.Estimate:
        """Eqs. 13–18 on ``frame`` (attributes in :mod:`.common`)."""
        t0 = time.perf_counter()
        est = self._measure(frame)
        est.t_ms = (time.perf_counter() - t0) * 1e3
        return est

    @staticmethod
    def _solve(pred, u: np.ndarray) -> np.ndarray | None:
        n = solve_n(sphere_rays(pred, u))
        return None if n is None else r_from_n(pred, n)

    def _measure(self, frame) -> common.Estimate:
        o = self.options
        pred, pts, failed = limb_points(frame, o.scan, o.min_radius_px, o.min_points)
        if failed is not None:
            return failed
        keep = np.ones(len(pts.ideal), bool)
        for _ in range(3):
            r = self._solve(pred, pts.ideal[keep])
            if r is None or o.reject_sigma <= 0:
                break
            new = inliers(pred, pts.ideal, r, keep, o.reject_sigma)
            if np.array_equal(new, keep) or new.sum() < o.min_points:
                break
            keep = new
        else:
            r = self._solve(pred, pts.ideal[keep])
        if r is None:
            return common.Estimate(reason=common.FIT_FAILED, limb_points=pts.image, diagnostics="nᵀn ≤ 1")
        est = common.Estimate(limb_points=pts.image[keep], diagnostics=f"points {keep.sum()}/{len(keep)}")
        ell = ellipse_params(cone_to_pixels(limb_cone(pred.U.T @ pred.U, r), pred.K))
        if ell is not None:
            est.set_ellipse(ell)
        return finish(est, frame, pred, pts.ideal[keep], r, o.edge_sigma_px)
