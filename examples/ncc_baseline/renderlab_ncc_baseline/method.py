"""A plain normalised-cross-correlation landmark method: the worked example of a renderlab plug-in.

Per landmark (:class:`NccBaseline`):

1. **Predict.** The maplet's image is rendered with the lab's template renderer
   (:func:`estimators.retina.predict.render_template`) at the a-priori pose, with the options the lab passes
   (``supersample``, ``psf_sigma_px``, ``L_table``).
2. **Mask.** Only the template's valid pixels (fully covered by the maplet) count: the template is cropped to
   the bounding box of its valid pixels, and the invalid pixels left inside that box (the corners of a
   maplet seen at an angle) are filled with the mean of the valid ones, so they carry no signal of their own.
   Near the edge of the image the box is clipped further to the part whose search window stays inside the
   image (a landmark partly off the image is measured on the part that is on it).
   Image pixels marked invalid in ``frame.valid`` (e.g. saturated) are likewise replaced by the mean of the
   usable pixels of the search window. This is a baseline, not a masked correlation: the filled pixels still
   enter the image-side normalisation.
3. **Correlate.** ``cv2.matchTemplate(window, template, cv2.TM_CCOEFF_NORMED)`` over the search window (the
   template box grown by the search distance r on every side): the correlation at every integer shift
   |Δs|, |Δl| ≤ r. Non-finite values (there should be none) count as −1.
4. **Peak.** The integer maximum, refined by the method's own 2-D quadric (:func:`quadric_peak`: a
   least-squares fit of ``a + b x + c y + d x² + e x y + f y²`` to the 3 × 3 neighbourhood, its stationary
   point).

``meas = pred + (Δs, Δl)``, as the contract says. Checks, in this order (the first that fails is the reason,
see :class:`~renderlab.contracts.reasons.LandmarkReason`):

- ``off_image``: the predicted centre is behind the camera or off the image, the template cannot be made, or
  the search window of every template pixel leaves the image;
- ``facing_away``: the maplet's up axis faces away from the sun or from the camera;
- ``too_few_pixels``: fewer than :data:`MIN_PIXELS` valid template pixels (after the clipping above), or fewer
  than that over usable image pixels at the peak;
- ``flat_template``: the valid template pixels have no contrast;
- ``search_border``: the integer peak lies on the border of the search window;
- ``low_correlation``: the peak correlation is under ``options.min_correlation``.

``options.peak`` is ignored: this method has its own peak finder (``peak = "quadric_ncc"``).
"""

from __future__ import annotations

import math
import time

import numpy as np

from renderlab.contracts.landmark import LandmarkFrame, LandmarkMethodOptions, LandmarkResult
from renderlab.contracts.reasons import LandmarkReason

#: the least number of valid template pixels (and of usable image pixels under them at the peak)
MIN_PIXELS = 64

_QX, _QY = (a.ravel() for a in np.meshgrid([-1.0, 0.0, 1.0], [-1.0, 0.0, 1.0]))
#: design matrix of the quadric a + b x + c y + d x² + e x y + f y² on the 3 × 3 grid (x: column, y: row)
_QUADRIC = np.column_stack([np.ones(9), _QX, _QY, _QX ** 2, _QX * _QY, _QY ** 2])


def _parabola(m: float, c: float, p: float) -> float:
    """Vertex of the parabola through (−1, m), (0, c), (1, p); 0 when it does not open downward."""
    den = m - 2.0 * c + p
    return 0.0 if den >= 0 else 0.5 * (m - p) / den


def quadric_peak(C3: np.ndarray) -> tuple[float, float]:
    """Sub-pixel offset of a correlation peak from its 3 × 3 neighbourhood.

    Parameters
    ----------
    C3 : (3, 3) array
        The correlation around the integer maximum (row = line, column = sample), maximum at the centre.

    Returns
    -------
    (dx, dy) : tuple of float
        Offset of the peak from the centre (sample, line), px, clamped to [−1, 1]. The stationary point of the
        least-squares quadric; where the quadric is not a maximum (its Hessian not negative definite), the
        vertices of the parabolas through the centre row and column instead.
    """
    z = np.asarray(C3, float).ravel()
    (_, b, c, d, e, f), *_ = np.linalg.lstsq(_QUADRIC, z, rcond=None)
    hessian = np.array([[2.0 * d, e], [e, 2.0 * f]])
    if d < 0 and np.linalg.det(hessian) > 0:
        dx, dy = np.linalg.solve(hessian, [-b, -c])
    else:
        dx, dy = _parabola(z[3], z[4], z[5]), _parabola(z[1], z[4], z[7])
    return float(min(max(dx, -1.0), 1.0)), float(min(max(dy, -1.0), 1.0))


def _faces_away(maplet, position_m: np.ndarray, sun_body: np.ndarray) -> bool:
    up = np.asarray(maplet.R_body_from_maplet, float)[:, 2]
    to_cam = np.asarray(position_m, float) - np.asarray(maplet.center_m, float)
    return bool(up @ np.asarray(sun_body, float) <= 0 or up @ to_cam <= 0)


def _crop_valid(tpl):
    """(template, valid, s0, l0) cropped to the bounding box of the valid pixels; None if there is none."""
    rows, cols = np.flatnonzero(tpl.valid.any(axis=1)), np.flatnonzero(tpl.valid.any(axis=0))
    if rows.size == 0:
        return None
    r0, r1, c0, c1 = rows[0], rows[-1] + 1, cols[0], cols[-1] + 1
    return tpl.image[r0:r1, c0:c1], tpl.valid[r0:r1, c0:c1], tpl.s0 + int(c0), tpl.l0 + int(r0)


def _clip_to_image(T, V, s0: int, l0: int, r: int, shape):
    """The part of the template whose search window (grown by ``r``) stays inside an image of ``shape``;
    None when no part does."""
    H, W = shape
    c0, c1 = max(0, r - s0), min(T.shape[1], W - r - s0)
    r0, r1 = max(0, r - l0), min(T.shape[0], H - r - l0)
    if c1 <= c0 or r1 <= r0:
        return None
    return T[r0:r1, c0:c1], V[r0:r1, c0:c1], s0 + c0, l0 + r0


def _correlate(window: np.ndarray, template: np.ndarray) -> np.ndarray:
    """TM_CCOEFF_NORMED of ``template`` over ``window`` (float32 after removing the means, so the single
    precision OpenCV works in keeps the differences); non-finite values → −1."""
    import cv2

    w = (window - window.mean()).astype(np.float32)
    t = (template - template.mean()).astype(np.float32)
    C = cv2.matchTemplate(w, t, cv2.TM_CCOEFF_NORMED).astype(np.float64)
    return np.where(np.isfinite(C), C, -1.0)


class NccBaseline:
    """Template prediction by the lab's renderer, OpenCV NCC, own quadric peak (module docstring).

    Parameters
    ----------
    options : LandmarkMethodOptions
        ``supersample``, ``psf_sigma_px`` and ``L_table`` go to the template renderer; ``min_correlation``
        is the result threshold; ``peak`` is ignored.
    """

    name = "ncc_baseline"
    peak = "quadric_ncc"

    def __init__(self, options: LandmarkMethodOptions = LandmarkMethodOptions()):
        from estimators.retina.predict import TemplateOptions

        self.template_options = TemplateOptions(supersample=int(options.supersample),
                                                psf_sigma_px=float(options.psf_sigma_px),
                                                L_table=tuple(options.L_table))
        self.min_correlation = float(options.min_correlation)
        self._meshes: dict[int, tuple] = {}

    def _mesh(self, maplet):
        from estimators.retina import build_mesh

        hit = self._meshes.get(id(maplet))
        if hit is None or hit[0] is not maplet:
            hit = (maplet, build_mesh(maplet))
            self._meshes[id(maplet)] = hit
        return hit[1]

    def measure_frame(self, frame: LandmarkFrame) -> list[LandmarkResult]:
        """One :class:`LandmarkResult` per ``frame.landmarks`` entry, in order."""
        return [self.measure_landmark(frame, k) for k in range(len(frame.landmarks))]

    def measure_landmark(self, frame: LandmarkFrame, k: int) -> LandmarkResult:
        """The shift of landmark ``k`` of ``frame`` (module docstring)."""
        from estimators.retina.predict import CameraPoseEstimate, project_point

        t0 = time.perf_counter()
        maplet, r = frame.landmarks[k], int(frame.search_px[k])
        pose = CameraPoseEstimate(np.asarray(frame.pose.R_body_from_cam, float),
                                  np.asarray(frame.pose.position_m, float))
        pred = project_point(frame.camera, pose, maplet.center_m)
        out = LandmarkResult(landmark_id=int(maplet.landmark_id), pred_s=float(pred[0]), pred_l=float(pred[1]),
                             search_px=r)
        reason, out.diagnostics = self._measure(frame, maplet, pose, pred, r, out)
        out.reason = reason.value
        if reason is not LandmarkReason.OK:
            out.ds = out.dl = math.nan
        out.t_ms = (time.perf_counter() - t0) * 1e3
        return out

    def _measure(self, frame, maplet, pose, pred, r, out) -> tuple[LandmarkReason, str]:
        """Fill ``out`` (shift, score, pixels, shadow fraction); return (reason, diagnostics)."""
        from estimators.retina.predict import render_template

        cam = frame.camera
        if not (np.all(np.isfinite(pred)) and bool(cam.in_image(pred))):
            return LandmarkReason.OFF_IMAGE, "predicted centre off the image"
        if _faces_away(maplet, pose.position_m, frame.sun_body):
            return LandmarkReason.FACING_AWAY, "maplet faces away from the sun or the camera"
        tpl = render_template(self._mesh(maplet), cam, pose, frame.sun_body, self.template_options)
        if tpl is None:
            return LandmarkReason.OFF_IMAGE, "no template (behind the camera, too large or too small)"
        out.shadow_fraction = float(tpl.shadow_fraction)
        crop = _crop_valid(tpl)
        if crop is None:
            return LandmarkReason.TOO_FEW_PIXELS, "no valid template pixel"
        crop = _clip_to_image(*crop, r, frame.image.shape)
        if crop is None:
            return LandmarkReason.OFF_IMAGE, "search window leaves the image"
        T, V, s0, l0 = crop
        h, w = T.shape
        n_valid = int(V.sum())
        if n_valid < MIN_PIXELS:
            return LandmarkReason.TOO_FEW_PIXELS, f"{n_valid} valid template pixels < {MIN_PIXELS}"
        vals = T[V]
        if not np.std(vals) > 1e-12 * max(abs(float(np.mean(vals))), 1e-300):
            return LandmarkReason.FLAT_TEMPLATE, "template without contrast"
        rows, cols = slice(l0 - r, l0 + h + r), slice(s0 - r, s0 + w + r)
        win = np.array(frame.image[rows, cols], dtype=np.float64)
        usable = np.ones(win.shape, bool) if frame.valid is None else np.asarray(frame.valid[rows, cols], bool)
        if not usable.any():
            return LandmarkReason.TOO_FEW_PIXELS, "no usable image pixel in the search window"
        win[~usable] = win[usable].mean()
        C = _correlate(win, np.where(V, T, vals.mean()))
        a, b = divmod(int(np.argmax(C)), C.shape[1])
        out.score = float(C[a, b])
        out.n_pixels = int((V & usable[a:a + h, b:b + w]).sum())
        diag = f"template {w}x{h} px, {h * w - n_valid} filled; {int((~usable).sum())} unusable image px"
        if out.n_pixels < MIN_PIXELS:
            return LandmarkReason.TOO_FEW_PIXELS, f"{out.n_pixels} usable pixels at the peak < {MIN_PIXELS}; {diag}"
        if a in (0, C.shape[0] - 1) or b in (0, C.shape[1] - 1):
            return LandmarkReason.SEARCH_BORDER, f"integer peak on the search border; {diag}"
        if out.score < self.min_correlation:
            return LandmarkReason.LOW_CORRELATION, f"peak {out.score:.3f} < {self.min_correlation}; {diag}"
        dx, dy = quadric_peak(C[a - 1:a + 2, b - 1:b + 2])
        out.ds, out.dl = float(b - r + dx), float(a - r + dy)
        return LandmarkReason.OK, diag
