r"""SPC-style landmark measurement: correlate in the maplet frame (Gaskell et al. 2008; Retina paper §
"Implementation motivation", Figs. 3, 10, 12).

Description
-----------
The method the Retina paper compares against, with the approximations it blames for SPC's bias (Fig. 12):

1. **Image into the maplet frame.** Every maplet grid point (x_i, y_j, h_ij), on a grid extended by the
   search distance, is projected with the a-priori pose (eqs. 1–4) and the image is sampled there
   (bilinear). When a maplet cell covers more than ~1.5 px the image is first averaged with a Gaussian of
   σ = 0.4 × (pixels per cell), so the extracted image has the maplet's resolution.
2. **Predicted image on the grid.** Each grid point is shaded with McEwen's law (eqs. 5–8) from the DEM
   normal by central differences (no facets, no sub-cell geometry) and the grid albedo.
   Shadows are *approximated* (not ray-traced): a point is shadowed if cos i ≤ 0, or if marching from it
   toward the sun in whole-cell steps along the sun's azimuth finds a grid height (nearest grid point)
   above the sun ray. Points predicted in shadow are thrown away from the correlation (the paper: "the
   SPC processing must throw away much of this data").
3. **Correlation** of predicted vs extracted (eq. 9) at every integer cell shift within the search
   distance converted to cells, **peak** by the 2-D quadric fit of the 3×3 neighbourhood.
4. **Back to the image.** A peak at (δx, δy) cells means the landmark centre appears where the a-priori
   pose projects the maplet point (δx s, δy s, 0): Δs, Δl = that pixel − the predicted pixel.

The maplet grid gives a cell-quantised view of the image: with GSD ≠ spacing, oblique views and heights
this is where SPC's approximations bite. The projection, correlation, peak finders, measurement and final output
phase are the landmark layer both methods share (:mod:`estimators.landmarks`); the onboard photometry
(``L_table``) is the same for both methods.

Tuning
------
:class:`SpcOptions`:

====================  ==========  ==============================================================================
knob                  default     turn it when
====================  ==========  ==============================================================================
``peak``              quadric_2d  SPC's quadric; any :data:`estimators.landmarks.peaks.FINDERS` name to compare
``min_correlation``   0.3         raise to refuse weak matches; lower on low-contrast terrain
``min_points``        64          lit grid points that must overlap the extracted image; lower for small maplets
``min_image_px``      9.0 px²     smallest image area of the maplet's footprint (``TOO_FEW_PIXELS`` below)
``drop_shadowed``     True        False keeps grid points predicted in shadow (their zeros) in the correlation
``cast_shadows``      True        False skips the horizon march (attached shadows cos i ≤ 0 only): for a truth
                                  rendered without cast shadows (``render.shadows = false``)
``alpha0``            π/3 rad     McEwen β = exp(−α/α0), used when ``L_table`` is empty
``ls_weight``         2           Lommel–Seeliger weight c (1: Retina eq. 5 as printed)
``L_table``           ()          L(α) fitted to the body's law; give both methods the same table
``outlier_k``         5.0         final output phase threshold in robust σ, as Retina's
``outlier_floor_px``  1.0 px      smallest flagged distance from the frame's median shift
====================  ==========  ==============================================================================

Use
---
::

    from estimators.landmarks import CameraPoseEstimate
    from estimators.spc import SpcOptions, measure_frame
    pose = CameraPoseEstimate(R_body_from_cam, position_m)          # a-priori, body frame
    res = measure_frame(dn_image, maplets, camera, pose, sun_body, search_px, SpcOptions())
    shifts = [(r.ds, r.dl) for r in res if r.has_result]            # px, image frame, as Retina's

References
----------
R. W. Gaskell, O. Barnouin-Jha, D. J. Scheeres, A. S. Konopliv, T. Mukai, S. Abe, J. Saito, M. Ishiguro,
T. Kubota, T. Hashimoto, et al., "Characterizing and navigating small bodies with imaging data", Meteoritics
& Planetary Science, Vol. 43, No. 6, 2008, pp. 1049–1061, doi:10.1111/j.1945-5100.2008.tb00692.x.

C. A. Wright, J. Van Eepoel, A. Liounis, M. Shoemaker, K. DeWeese, K. Getzandanner, "Relative Terrain Imaging
Navigation (RETINA) Tool for the Asteroid Redirect Robotic Mission (ARRM)", NASA Goddard Space Flight Center,
2016 (equation numbers above; a technical report, no DOI).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from numba import njit

from estimators import flags as F
from estimators.landmarks.correlation import correlation_surface
from estimators.landmarks.measurement import LandmarkMeasurement, facing_flags, final_output_phase
from estimators.landmarks.peaks import locate_peak
from estimators.landmarks.pose import CameraPoseEstimate, project_point
from estimators.onboard_photometry import DEFAULT_ALPHA0, mcewen_relative
from renderlab.geometry.camera import CameraModel
from renderlab.geometry.maplet import Maplet


@dataclass(frozen=True)
class SpcOptions:
    """SPC-style settings (see the module docstring).

    Attributes
    ----------
    alpha0, ls_weight : float
        McEwen parameters.
    L_table : tuple of float
        L(α) tabulated over [0, π] replacing β = exp(−α/α0) (empty: the exponential;
        :func:`estimators.onboard_photometry.fit_lunar_lambert_L`). The Retina-vs-SPC study gives both
        methods the same table, so their differences come from the approximations under test.
    min_correlation : float
        Peaks under this correlation give no result.
    min_points : int
        Minimum lit grid points overlapping the extracted image.
    peak : str
        Peak finder (SPC: ``quadric_2d``).
    drop_shadowed : bool
        Throw away grid points predicted in shadow (SPC's practice).
    cast_shadows : bool
        Predict cast shadows by the horizon march (False: attached shadows only, cos i ≤ 0).
    outlier_k, outlier_floor_px : float
        Final output phase, as Retina's.
    min_image_px : float
        Smallest image area (px²) the maplet's footprint may cover; a smaller landmark (too far away) gives no
        result (``TOO_FEW_PIXELS``): a few pixels cannot locate a correlation peak.
    """

    alpha0: float = DEFAULT_ALPHA0
    ls_weight: float = 2.0
    L_table: tuple = ()
    min_correlation: float = 0.3
    min_points: int = 64
    peak: str = "quadric_2d"
    drop_shadowed: bool = True
    cast_shadows: bool = True
    outlier_k: float = 5.0
    outlier_floor_px: float = 1.0
    min_image_px: float = 9.0


def _grid_normals(h: np.ndarray, s: float) -> np.ndarray:
    gy, gx = np.gradient(h, s)
    n = np.stack([-gx, -gy, np.ones_like(h)], axis=-1)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


@njit(cache=True)
def _horizon(h, s, ux, uy, tan_e):
    n = h.shape[0]
    out = np.zeros(h.shape, np.bool_)
    kmax = int(math.ceil(math.sqrt(2.0) * n))
    for j in range(n):
        for i in range(n):
            for k in range(1, kmax + 1):
                ci = int(np.rint(i + k * ux))
                cj = int(np.rint(j + k * uy))
                if ci < 0 or ci >= n or cj < 0 or cj >= n:
                    break
                if h[cj, ci] > h[j, i] + k * s * tan_e:
                    out[j, i] = True
                    break
    return out


def approximate_shadow(h: np.ndarray, s: float, sun_m: np.ndarray) -> np.ndarray:
    """Horizon-march shadow test on the grid (whole-cell steps, nearest grid point) → bool (n, n)."""
    horiz = math.hypot(sun_m[0], sun_m[1])
    if horiz < 1e-9:
        return np.zeros(np.shape(h), bool)
    return _horizon(np.ascontiguousarray(h, dtype=np.float64), float(s), sun_m[0] / horiz, sun_m[1] / horiz,
                    sun_m[2] / horiz)


def predict_maplet(maplet: Maplet, to_cam_m: np.ndarray, sun_m: np.ndarray, options: SpcOptions = SpcOptions()):
    """SPC's predicted brightness on the maplet grid → (image (n, n), usable (n, n) bool)."""
    h = np.asarray(maplet.heights_m, float)
    s = float(maplet.spacing_m)
    nrm = _grid_normals(h, s)
    r = to_cam_m / np.linalg.norm(to_cam_m)
    cos_i, cos_r = nrm @ sun_m, nrm @ r
    phase = math.acos(float(np.clip(sun_m @ r, -1, 1)))
    img = mcewen_relative(cos_i, cos_r, phase, maplet.albedo, options.alpha0, options.ls_weight,
                          options.L_table or None)
    shadow = (cos_i <= 0) | (approximate_shadow(h, s, sun_m) if options.cast_shadows else False)
    img = np.where(shadow, 0.0, img)
    usable = ~shadow if options.drop_shadowed else np.ones(h.shape, bool)
    return img, usable & (cos_r > 0)


def _px_per_cell(camera, pose, maplet) -> float:
    R = np.asarray(maplet.R_body_from_maplet, float)
    J = camera.project_jacobian(pose.to_camera(maplet.center_m)) @ np.asarray(pose.R_body_from_cam, float).T
    return float(np.sqrt(abs(np.linalg.det(J @ R[:, :2])))) * float(maplet.spacing_m)


def extract_in_maplet(image: np.ndarray, camera: CameraModel, pose: CameraPoseEstimate, maplet: Maplet,
                      pad: int, px_per_cell: float | None = None):
    """Sample the image at the a-priori projections of the grid points extended by ``pad`` cells.

    Returns ``(E (n+2p, n+2p), ok)``; heights outside the maplet are the edge heights.
    """
    import cv2

    n, s = maplet.n, float(maplet.spacing_m)
    h = np.pad(np.asarray(maplet.heights_m, float), pad, mode="edge")
    t = (np.arange(n + 2 * pad) - (n + 2 * pad - 1) / 2) * s
    X, Y = np.meshgrid(t, t)
    sl = project_point(camera, pose, maplet.to_body(np.stack([X, Y, h], axis=-1)))
    img = np.asarray(image, np.float64)
    ppc = _px_per_cell(camera, pose, maplet) if px_per_cell is None else px_per_cell
    if ppc > 1.5:
        img = cv2.GaussianBlur(img, (0, 0), 0.4 * ppc, borderType=cv2.BORDER_REPLICATE)
    ok = np.all(np.isfinite(sl), axis=-1) & (sl[..., 0] >= 0) & (sl[..., 0] <= img.shape[1] - 1) \
        & (sl[..., 1] >= 0) & (sl[..., 1] <= img.shape[0] - 1)
    # float64 bilinear sampling (cv2.remap quantises positions to 1/32 px, a bias of its own)
    from scipy.ndimage import map_coordinates

    coords = np.stack([np.where(ok, sl[..., 1], 0.0), np.where(ok, sl[..., 0], 0.0)])
    E = np.where(ok, map_coordinates(img.astype(np.float64), coords, order=1, mode="nearest"), 0.0)
    return E.astype(np.float64), ok


def measure_landmark(image: np.ndarray, maplet: Maplet, camera: CameraModel, pose: CameraPoseEstimate,
                     sun_body: np.ndarray, search_px: int, options: SpcOptions = SpcOptions(),
                     image_valid: np.ndarray | None = None) -> LandmarkMeasurement:
    """SPC-style (Δs, Δl) of one landmark (module docstring). ``image_valid`` is accepted for symmetry
    with Retina; masked pixels are treated as outside the image."""
    t0 = time.perf_counter()
    pred = project_point(camera, pose, maplet.center_m)
    out = LandmarkMeasurement(int(maplet.landmark_id), float(pred[0]), float(pred[1]))
    try:
        if not np.all(np.isfinite(pred)):
            out.flags |= F.OFF_IMAGE
            return out
        out.flags |= facing_flags(maplet, pose, sun_body)
        if out.flags:
            return out
        ppc = _px_per_cell(camera, pose, maplet)
        if (maplet.heights_m.shape[0] * ppc) ** 2 < options.min_image_px:
            out.flags |= F.TOO_FEW_PIXELS
            return out
        r = int(max(2, math.ceil(search_px / max(ppc, 1e-9))))
        out.search_px = int(search_px)
        R_mb = np.asarray(maplet.R_body_from_maplet, float).T
        sun_m = R_mb @ (np.asarray(sun_body, float) / np.linalg.norm(sun_body))
        to_cam_m = R_mb @ (np.asarray(pose.position_m, float) - np.asarray(maplet.center_m, float))
        P, usable = predict_maplet(maplet, to_cam_m, sun_m, options)
        out.shadow_fraction = float(1.0 - usable.mean())
        E, ok = extract_in_maplet(image, camera, pose, maplet, r, ppc)
        if image_valid is not None:
            ok &= _valid_at(image_valid, camera, pose, maplet, r)
        if usable.sum() < options.min_points or np.ptp(P[usable]) <= 0:
            out.flags |= F.FLAT_TEMPLATE if usable.sum() >= options.min_points else F.TOO_FEW_PIXELS
            return out
        C, cnt = correlation_surface(E, P, usable, r, r, r, ok, options.min_points)
        peak = locate_peak(C, options.peak)
        if peak is None:
            out.flags |= F.OFF_IMAGE if cnt.max() == 0 else F.TOO_FEW_PIXELS
            return out
        out.score = peak.score
        out.n_pixels = int(cnt[int(round(peak.dl)) + r, int(round(peak.ds)) + r])
        if peak.on_border:
            out.flags |= F.SEARCH_BORDER
        if peak.score < options.min_correlation:
            out.flags |= F.LOW_CORRELATION
        if not out.flags:
            s = float(maplet.spacing_m)
            meas = project_point(camera, pose, maplet.to_body(np.array([peak.ds * s, peak.dl * s, 0.0])))
            out.ds, out.dl = float(meas[0] - pred[0]), float(meas[1] - pred[1])
        return out
    finally:
        out.t_ms = (time.perf_counter() - t0) * 1e3


def _valid_at(image_valid, camera, pose, maplet, pad):
    n, s = maplet.n, float(maplet.spacing_m)
    h = np.pad(np.asarray(maplet.heights_m, float), pad, mode="edge")
    t = (np.arange(n + 2 * pad) - (n + 2 * pad - 1) / 2) * s
    X, Y = np.meshgrid(t, t)
    sl = project_point(camera, pose, maplet.to_body(np.stack([X, Y, h], axis=-1)))
    ij = np.rint(np.nan_to_num(sl, nan=-1)).astype(int)
    H, W = image_valid.shape
    inside = (ij[..., 0] >= 0) & (ij[..., 0] < W) & (ij[..., 1] >= 0) & (ij[..., 1] < H)
    return inside & np.asarray(image_valid, bool)[np.clip(ij[..., 1], 0, H - 1), np.clip(ij[..., 0], 0, W - 1)]


def measure_frame(image: np.ndarray, maplets: list[Maplet], camera: CameraModel, pose: CameraPoseEstimate,
                  sun_body: np.ndarray, search_px: list[int], options: SpcOptions = SpcOptions(),
                  image_valid: np.ndarray | None = None) -> list[LandmarkMeasurement]:
    """All landmarks of one image, then the same final output phase as Retina."""
    res = [measure_landmark(image, m, camera, pose, sun_body, r, options, image_valid)
           for m, r in zip(maplets, search_px)]
    final_output_phase(res, options.outlier_k, options.outlier_floor_px)
    return res
