r"""Retina per landmark and per frame: predict → correlate (eq. 9) → peak → final output phase.

Description
-----------
For each landmark: the maplet is projected with the a-priori pose (eqs. 1–4); its synthetic image is
ray-traced and lit with McEwen's law (eqs. 5–8, :mod:`.predict`); the correlation coefficient (eq. 9) is
computed at every integer shift within the search distance (:mod:`estimators.landmarks.correlation`); the peak is located to
sub-pixel precision (:mod:`estimators.landmarks.peaks`, the paper's 3×3 interpolation by default). The measured shift
(Δs, Δl) moves the predicted landmark pixel onto the observed one: ``meas = pred + (Δs, Δl)``.

No result (NaN shift, a flag of :mod:`estimators.flags`), checked in this order: prediction behind the
camera (``OFF_IMAGE``); maplet up axis facing away from the sun or the camera (``FACING_AWAY``); no template
(off the image or larger than ``max_size_px``: ``OFF_IMAGE``); fewer than ``min_pixels`` valid template
pixels (``TOO_FEW_PIXELS``) or no contrast (``FLAT_TEMPLATE``); no shift with ``min_pixels`` of overlap
(``OFF_IMAGE`` / ``TOO_FEW_PIXELS``); integer peak on the border of the search area (``SEARCH_BORDER``)
and/or peak correlation under ``min_correlation`` (``LOW_CORRELATION``).

Final output phase (paper, "Final Output Phase"): all shifts of a frame should agree, since they come
from one pose error. Each shift is compared with the frame's median shift; those farther than
``max(outlier_floor_px, outlier_k · 1.4826 · MAD)`` are flagged :data:`~estimators.flags.OUTLIER` for
the filter, not dropped. (The paper compares with the mean; the median is not dragged by the outliers
it is looking for.) With fewer than three results nothing is flagged.

Tuning
------
:class:`RetinaOptions` (the synthetic-image knobs of ``template`` are listed in :mod:`estimators.retina`):

====================  ============  ========================================================================
knob                  default       turn it when
====================  ============  ========================================================================
``peak``              retina_3x3    compare finders (``parabola_1d``, ``quadric_2d``, ``gaussian``,
                                    ``gaussian_2d``, ``upsampled``): :func:`~estimators.landmarks.peaks.pixel_locking_curve` shows
                                    each one's bias
``min_correlation``   0.3           raise to refuse weak matches (fewer results, fewer gross errors); lower
                                    on low-contrast terrain
``min_pixels``        64            overlapping valid pixels required; lower for small or distant maplets
``outlier_k``         5.0           final output phase threshold in robust σ; lower to flag more
``outlier_floor_px``  1.0 px        smallest flagged distance from the median shift (keeps tight frames clean)
``recentre_passes``   0             re-centred passes after the finder (:mod:`.recentre`: the template moved by
                                    the sub-pixel estimate, eq. 9 and the finder again at zero offset); 2 with
                                    ``gaussian_2d`` is the lab's refined step (``retina_refined``)
``refine``            ""            a refinement of :data:`~.ml_shift.REFINEMENTS` after those: ``ml_shift``, the
                                    maximum-likelihood shift by Gauss–Newton on the template (:mod:`.ml_shift`;
                                    with ``gaussian_2d``: the ``retina_ml`` method); "" = none
====================  ============  ========================================================================

Use
---
::

    from estimators.retina import CameraPoseEstimate, RetinaOptions, build_mesh, measure_landmark
    mesh = build_mesh(maplet)                                   # once per maplet
    pose = CameraPoseEstimate(R_body_from_cam, position_m)      # a-priori, body frame
    m = measure_landmark(dn_image, mesh, camera, pose, sun_body, 8, RetinaOptions(peak="quadric_2d"))
    m.has_result, (m.meas_s, m.meas_l), m.score, m.flags       # flags: estimators.flags bits

References
----------
C. A. Wright, J. Van Eepoel, A. Liounis, M. Shoemaker, K. DeWeese, K. Getzandanner, "Relative Terrain Imaging
Navigation (RETINA) Tool for the Asteroid Redirect Robotic Mission (ARRM)", NASA Goddard Space Flight Center,
2016 (sections "Correlation Method", "Peak Finding", "Final Output Phase").
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from estimators import flags as F
from estimators.landmarks.correlation import correlation_surface
from estimators.landmarks.measurement import LandmarkMeasurement, facing_flags, final_output_phase
from estimators.landmarks.peaks import locate_peak
from estimators.landmarks.pose import CameraPoseEstimate, project_point
from estimators.retina.maplet_mesh import MapletMesh
from estimators.retina.ml_shift import REFINEMENTS
from estimators.retina.predict import TemplateOptions, render_template
from estimators.retina.recentre import recentred_shift
from renderlab.geometry.camera import CameraModel


@dataclass(frozen=True)
class RetinaOptions:
    """Retina settings.

    Attributes
    ----------
    template : TemplateOptions
        Synthetic image options (supersampling, PSF, McEwen parameters, shadow rays).
    peak : str
        Peak finder (see :data:`estimators.landmarks.peaks.FINDERS`).
    min_correlation : float
        Peaks under this correlation are flagged ``LOW_CORRELATION`` (no result).
    min_pixels : int
        Minimum overlapping valid pixels at the peak.
    outlier_k, outlier_floor_px : float
        Final output phase threshold (module docstring).
    recentre_passes : int
        Re-centred peak passes after the finder (:func:`~.recentre.recentred_shift`); 0 = the finder alone.
    refine : str
        Refinement after the finder and passes, a name of :data:`~.ml_shift.REFINEMENTS`; "" = none.

    Raises
    ------
    ValueError
        An unknown refinement (an unknown finder is refused by :func:`~estimators.landmarks.peaks.locate_peak`).
    """

    template: TemplateOptions = field(default_factory=TemplateOptions)
    peak: str = "retina_3x3"
    min_correlation: float = 0.3
    min_pixels: int = 64
    outlier_k: float = 5.0
    outlier_floor_px: float = 1.0
    recentre_passes: int = 0
    refine: str = ""

    def __post_init__(self):
        if self.refine and self.refine not in REFINEMENTS:
            raise ValueError(f"unknown peak refinement {self.refine!r} (choose from {', '.join(REFINEMENTS)}, "
                             "or '' for none)")


def measure_landmark(image: np.ndarray, mesh: MapletMesh, camera: CameraModel, pose: CameraPoseEstimate,
                     sun_body: np.ndarray, search_px: int, options: RetinaOptions = RetinaOptions(),
                     image_valid: np.ndarray | None = None) -> LandmarkMeasurement:
    """Measure one landmark's (Δs, Δl) in ``image`` (see the module docstring)."""
    t0 = time.perf_counter()
    M = mesh.maplet
    pred = project_point(camera, pose, M.center_m)
    out = LandmarkMeasurement(int(M.landmark_id), float(pred[0]), float(pred[1]), search_px=int(search_px))
    try:
        if not np.all(np.isfinite(pred)):
            out.flags |= F.OFF_IMAGE
            return out
        out.flags |= facing_flags(mesh, pose, sun_body)
        if out.flags:
            return out
        tpl = render_template(mesh, camera, pose, sun_body, options.template)
        if tpl is None:
            out.flags |= F.OFF_IMAGE
            return out
        out.shadow_fraction = tpl.shadow_fraction
        v = tpl.image[tpl.valid]
        if v.size < options.min_pixels or np.ptp(v) <= 0:
            out.flags |= F.FLAT_TEMPLATE if v.size >= options.min_pixels else F.TOO_FEW_PIXELS
            return out
        C, cnt = correlation_surface(image, tpl.image, tpl.valid, tpl.s0, tpl.l0, int(search_px),
                                     image_valid, options.min_pixels)
        peak = locate_peak(C, options.peak)
        if peak is None:
            out.flags |= F.OFF_IMAGE if cnt.max() == 0 else F.TOO_FEW_PIXELS
            return out
        r = int(search_px)
        out.n_pixels = int(cnt[int(round(peak.dl)) + r, int(round(peak.ds)) + r])
        out.score = peak.score
        if peak.on_border:
            out.flags |= F.SEARCH_BORDER
        if peak.score < options.min_correlation:
            out.flags |= F.LOW_CORRELATION
        if not out.flags:
            out.ds, out.dl = peak.ds, peak.dl
            if options.recentre_passes > 0:
                out.ds, out.dl = recentred_shift(image, tpl.image, tpl.valid, tpl.s0, tpl.l0, peak.ds, peak.dl,
                                                 options.peak, options.recentre_passes, image_valid,
                                                 options.min_pixels)
            if options.refine:
                out.ds, out.dl = REFINEMENTS[options.refine](image, tpl.image, tpl.valid, tpl.s0, tpl.l0, out.ds,
                                                             out.dl, image_valid, options.min_pixels)
        return out
    finally:
        out.t_ms = (time.perf_counter() - t0) * 1e3


def measure_frame(image: np.ndarray, meshes: list[MapletMesh], camera: CameraModel, pose: CameraPoseEstimate,
                  sun_body: np.ndarray, search_px: list[int], options: RetinaOptions = RetinaOptions(),
                  image_valid: np.ndarray | None = None) -> list[LandmarkMeasurement]:
    """All landmarks of one image, then the final output phase."""
    res = [measure_landmark(image, m, camera, pose, sun_body, r, options, image_valid)
           for m, r in zip(meshes, search_px)]
    final_output_phase(res, options.outlier_k, options.outlier_floor_px)
    return res
