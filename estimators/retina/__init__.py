"""Retina (Wright et al., ARRM): landmark measurement by ray-traced prediction and correlation.

Description
-----------
Retina measures, in one image, the shift (Δs, Δl) of every catalogued landmark (maplet: a small DEM with
relative albedo) between where the a-priori pose predicts it and where the image shows it:
``meas = pred + (Δs, Δl)``. Per landmark:

1. **Project** the maplet with the a-priori pose and the camera model: x_C = T_C^B (x_B − t_B) (eqs. 1–2),
   gnomonic projection (eq. 3), distortion, pixel map K (eq. 4); the search distance is n_σ times the
   projected a-priori pose covariance (:func:`search_radius_px`).
2. **Predict** the landmark's image (Retina "Synthetic Image Generation"): the lines of sight of the pixels
   covering the maplet hit its facets, a shadow ray from each hit toward the sun decides cast shadows, and
   each lit hit gets McEwen's law, I = a[(1 − β) cos i + c β cos i / (cos i + cos r)], β = exp(−α/α0)
   (eqs. 5–8) or a fitted L(α) table; k × k samples per pixel, optional PSF (:mod:`.predict`, :mod:`.raster`,
   :mod:`.raytrace`).
3. **Correlate** (eq. 9, with the square root that makes it a correlation coefficient) at every integer
   shift within the search distance, by FFT (:mod:`estimators.landmarks.correlation`).
4. **Peak** to sub-pixel precision, by default the paper's "linear interpolation over a 3×3 sub-pixel
   grid" (``retina_3x3``; :mod:`estimators.landmarks.peaks`, with the other finders and the pixel-locking curve, :mod:`.locking`).
   The lab's refined step (``peak="gaussian_2d"``, ``recentre_passes=2``: a 2-D Gaussian fit, then the template
   moved by the sub-pixel estimate and the fit repeated at zero offset, :mod:`.recentre`) locks ≈ 0.01 px where
   the 3×3 step locks 0.04–0.07 px (:mod:`.peak_step`, ``benchmarks/bench_retina_peak_step.py``). The
   maximum-likelihood step (``refine="ml_shift"`` after ``gaussian_2d``, the ``retina_ml`` method: Gauss–Newton on
   the template's own pixels with gain and offset, :mod:`.ml_shift`) comes closest to the Cramér–Rao bound.
5. **Final output phase**: shifts inconsistent with the frame's median shift are flagged ``OUTLIER`` for the
   filter, not dropped (:mod:`.landmarks`).

Modules: :mod:`.maplet_mesh` (pre-processing), :mod:`.raytrace` (numba ray–facet and shadow rays),
:mod:`.predict` (synthetic image eqs. 5–8), :mod:`.landmarks` (per landmark and per frame), :mod:`.raster` (the default rasterised synthetic image), :mod:`.locking`
(pixel-locking curve on Retina-rendered maplets), :mod:`.recentre` (re-centred peak passes), :mod:`.ml_shift`
(maximum-likelihood shift), :mod:`.peak_step`
(bias and noise of the peak steps on cases with a known shift). No result is a bit in :mod:`estimators.flags`.
What Retina shares with SPC is in :mod:`estimators.landmarks`: the a-priori pose, projection (eqs. 1–4) and
search distance, the correlation (eq. 9), the sub-pixel peak finders and the pixel-locking curve, the
measurement and the final output phase.

Tuning
------
:class:`RetinaOptions` (``peak``, ``min_correlation``, ``min_pixels``, ``outlier_k``, ``outlier_floor_px``;
see :mod:`.landmarks`) and its ``template`` (:class:`TemplateOptions`):

====================  =========  ===========================================================================
knob                  default    turn it when
====================  =========  ===========================================================================
``supersample``       3          k × k rays per pixel: raise when maplet cells are much finer than a pixel
``psf_sigma_px``      0          set to the camera's PSF σ, so the prediction is as blurred as the image
``alpha0``            π/3 rad    McEwen β = exp(−α/α0) decay (eq. 5), used when ``L_table`` is empty
``ls_weight``         2          weight c of the Lommel–Seeliger term (2: McEwen; 1: eq. 5 as printed)
``L_table``           ()         L(α) tabulated over [0, π] fitted to the body's law
                                 (:func:`estimators.onboard_photometry.fit_lunar_lambert_L`) replaces β
``shadow_rays``       True       False keeps attached shadows only (cos i ≤ 0): what cast shadows are worth
``tracer``            raster     ``numba``: the ray-cast reference; ``numpy``: the slow baseline
``max_size_px``       256        templates larger on a side are refused (``OFF_IMAGE``): landmark too close
``shadow_grid_step``  0.5        spacing of the sun-aligned shadow sweep, maplet cells (``raster`` only)
====================  =========  ===========================================================================

:func:`search_radius_px` (``n_sigma`` = 3, ``min_px`` = 2, ``max_px`` = 64): widen ``n_sigma`` when the a-priori
covariance is optimistic; a landmark whose peak lands on the border gets ``SEARCH_BORDER``.

Use
---
::

    from estimators.retina import CameraPoseEstimate, RetinaOptions, build_mesh, measure_frame, search_radius_px
    pose = CameraPoseEstimate(R_body_from_cam, position_m)               # a-priori, body frame
    meshes = [build_mesh(m) for m in maplets]                            # once per catalog
    radii = [search_radius_px(camera, pose, m.center_m, cov_pos_m2, cov_rot_rad2) for m in maplets]
    res = measure_frame(dn_image, meshes, camera, pose, sun_body, radii, RetinaOptions())
    shifts = [(r.ds, r.dl) for r in res if r.has_result]                 # px; r.flags says why not

References
----------
C. A. Wright, J. Van Eepoel, A. Liounis, M. Shoemaker, K. DeWeese, K. Getzandanner, "Relative Terrain Imaging
Navigation (RETINA) Tool for the Asteroid Redirect Robotic Mission (ARRM)", NASA Goddard Space Flight Center,
2016 (a technical report: it has no DOI). Equation numbers above are this paper's.

J. P. Lewis, "Fast normalized cross-correlation", Vision Interface, Vol. 10, 1995, pp. 120–123 (the paper's
ref. 19; :mod:`estimators.landmarks.correlation`; no DOI).
"""

from estimators.landmarks import (
                                  CameraPoseEstimate,
                                  LandmarkMeasurement,
                                  final_output_phase,
                                  pixel_covariance,
                                  project_point,
                                  search_radius_px,
)
from estimators.retina.landmarks import RetinaOptions, measure_frame, measure_landmark
from estimators.retina.maplet_mesh import MapletMesh, build_mesh
from estimators.retina.predict import TemplateOptions, render_template

__all__ = ["LandmarkMeasurement", "RetinaOptions", "final_output_phase", "measure_frame", "measure_landmark",
           "MapletMesh", "build_mesh", "CameraPoseEstimate", "TemplateOptions", "pixel_covariance",
           "project_point", "render_template", "search_radius_px"]
