"""The lab's own landmark methods behind the :class:`~renderlab.contracts.landmark.LandmarkMethod` contract:
Retina (:mod:`estimators.retina`), Retina with the refined peak step (``retina_refined``: the 2-D Gaussian fit
``gaussian_2d`` of :mod:`estimators.landmarks.peaks` instead of the paper's 3×3 step), Retina with the
maximum-likelihood shift (``retina_ml``: :mod:`estimators.retina.ml_shift` after ``gaussian_2d``) and the SPC-style method
(:mod:`estimators.spc`).

The estimators stay self-contained (numpy/numba, their own result type with a bit mask of
:mod:`estimators.flags`); these adapters translate that mask into the contract's ``reason`` (first applicable
in :class:`~renderlab.contracts.reasons.LandmarkReason` order), ``outlier`` (the final output phase's flag,
kept) and ``diagnostics`` (the mask spelled out).
"""

from __future__ import annotations

from estimators import flags as F
from estimators.retina import CameraPoseEstimate, RetinaOptions, TemplateOptions, build_mesh
from estimators.spc import SpcOptions
from renderlab.contracts.landmark import LandmarkFrame, LandmarkMethodOptions, LandmarkResult
from renderlab.contracts.reasons import LandmarkReason

#: estimator flag name → contract reason, in priority order
_REASON_OF_FLAG = (("off_image", LandmarkReason.OFF_IMAGE), ("facing_away", LandmarkReason.FACING_AWAY),
                   ("too_few_pixels", LandmarkReason.TOO_FEW_PIXELS), ("flat_template", LandmarkReason.FLAT_TEMPLATE),
                   ("search_border", LandmarkReason.SEARCH_BORDER),
                   ("low_correlation", LandmarkReason.LOW_CORRELATION))


def result_from_estimator(m) -> LandmarkResult:
    """:class:`estimators.retina.LandmarkMeasurement` → :class:`LandmarkResult`."""
    names = {F.NAMES[b] for b in F.NAMES if m.flags & b}
    if m.has_result:
        reason, ds, dl = LandmarkReason.OK, float(m.ds), float(m.dl)
    else:
        reason = next((r for n, r in _REASON_OF_FLAG if n in names), LandmarkReason.NO_DETECTION)
        ds = dl = float("nan")
    return LandmarkResult(landmark_id=int(m.landmark_id), pred_s=float(m.pred_s), pred_l=float(m.pred_l), ds=ds, dl=dl,
                          score=float(m.score), reason=reason.value, outlier=bool(m.flags & F.OUTLIER),
                          search_px=int(m.search_px), n_pixels=int(m.n_pixels),
                          shadow_fraction=float(m.shadow_fraction), diagnostics=F.describe(m.flags), t_ms=float(m.t_ms))


def _pose(frame: LandmarkFrame):
    return CameraPoseEstimate(frame.pose.R_body_from_cam, frame.pose.position_m)


class RetinaMethod:
    """Retina (Wright et al.): ray-traced maplet prediction with shadow rays, McEwen shading, eq. 9 correlation,
    sub-pixel peak (the paper's 3×3 step by default), final output phase."""

    name = "retina"
    #: the peak finder used when ``options.peak`` is None (the paper's step, to reproduce the paper)
    default_peak = "retina_3x3"
    #: re-centred peak passes after the finder (:mod:`estimators.retina.recentre`); 0 = the finder alone
    recentre_passes = 0
    #: refinement after those (:data:`estimators.retina.ml_shift.REFINEMENTS`); "" = none
    refine = ""

    def __init__(self, options: LandmarkMethodOptions = LandmarkMethodOptions()):
        self.options = RetinaOptions(template=TemplateOptions(supersample=options.supersample,
                                                              psf_sigma_px=options.psf_sigma_px,
                                                              L_table=tuple(options.L_table)),
                                     peak=options.peak or self.default_peak, min_correlation=options.min_correlation,
                                     recentre_passes=self.recentre_passes, refine=self.refine)
        self.peak = (self.options.peak + (f"+recentre{self.recentre_passes}" if self.recentre_passes else "")
                     + (f"+{self.refine}" if self.refine else ""))
        self._meshes: dict[int, tuple] = {}

    def _mesh(self, maplet):
        hit = self._meshes.get(id(maplet))
        if hit is None or hit[0] is not maplet:
            hit = (maplet, build_mesh(maplet))
            self._meshes[id(maplet)] = hit
        return hit[1]

    def measure_frame(self, frame: LandmarkFrame) -> list[LandmarkResult]:
        from estimators.retina import measure_frame

        meshes = [self._mesh(m) for m in frame.landmarks]
        res = measure_frame(frame.image, meshes, frame.camera, _pose(frame), frame.sun_body,
                            [int(r) for r in frame.search_px], self.options, frame.valid)
        return [result_from_estimator(r) for r in res]


class RetinaRefinedMethod(RetinaMethod):
    """Retina with the refined sub-pixel step: a 2-D Gaussian (quadric on log C, full covariance) on the 3×3
    neighbourhood of the eq. 9 peak (``gaussian_2d``), then two re-centred passes (the template moved by the
    sub-pixel estimate, eq. 9 and the fit again at zero offset; :mod:`estimators.retina.recentre`), chosen from
    the pixel-locking and noise-vs-CRLB tables of ``benchmarks/bench_retina_peak_step.py``; everything else as
    :class:`RetinaMethod`. The ``peak`` column reads ``gaussian_2d+recentre2``."""

    name = "retina_refined"
    default_peak = "gaussian_2d"
    recentre_passes = 2


class RetinaMlMethod(RetinaMethod):
    """Retina with the maximum-likelihood shift: the ``gaussian_2d`` peak, then Gauss–Newton on the template's own
    pixels, gain and offset (:mod:`estimators.retina.ml_shift`), chosen from the bias and noise-vs-CRLB tables of
    ``benchmarks/bench_retina_peak_step.py``; everything else as :class:`RetinaMethod`. The ``peak`` column reads
    ``gaussian_2d+ml_shift``."""

    name = "retina_ml"
    default_peak = "gaussian_2d"
    refine = "ml_shift"


class SpcMethod:
    """SPC-style (Gaskell et al.): image resampled into the maplet frame, grid shading with approximate shadows,
    correlation and quadric peak in the maplet frame, final output phase."""

    name = "spc"

    def __init__(self, options: LandmarkMethodOptions = LandmarkMethodOptions()):
        self.options = SpcOptions(peak=options.peak or "quadric_2d", min_correlation=options.min_correlation,
                                  L_table=tuple(options.L_table))
        self.peak = self.options.peak

    def measure_frame(self, frame: LandmarkFrame) -> list[LandmarkResult]:
        from estimators.spc import measure_frame

        res = measure_frame(frame.image, list(frame.landmarks), frame.camera, _pose(frame), frame.sun_body,
                            [int(r) for r in frame.search_px], self.options, frame.valid)
        return [result_from_estimator(r) for r in res]
