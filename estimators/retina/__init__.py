"""Retina (Wright et al., ARRM): landmark measurement by ray-traced prediction and correlation.

Modules: :mod:`.maplet_mesh` (pre-processing), :mod:`.raytrace` (numba ray–facet and shadow rays),
:mod:`.predict` (projection eqs. 1–4, search distance, synthetic image eqs. 5–8), :mod:`.correlation`
(eq. 9), :mod:`.peaks` (sub-pixel peak finders, pixel-locking curve), :mod:`.landmarks` (per landmark and
per frame, final output phase), :mod:`.raster` (the default rasterised synthetic image), :mod:`.locking`
(pixel-locking curve on Retina-rendered maplets).
"""

from estimators.retina.landmarks import (LandmarkMeasurement, RetinaOptions, final_output_phase,
                                         measure_frame, measure_landmark)
from estimators.retina.maplet_mesh import MapletMesh, build_mesh
from estimators.retina.predict import (CameraPoseEstimate, TemplateOptions, pixel_covariance, project_point,
                                       render_template, search_radius_px)

__all__ = ["LandmarkMeasurement", "RetinaOptions", "final_output_phase", "measure_frame", "measure_landmark",
           "MapletMesh", "build_mesh", "CameraPoseEstimate", "TemplateOptions", "pixel_covariance",
           "project_point", "render_template", "search_radius_px"]
