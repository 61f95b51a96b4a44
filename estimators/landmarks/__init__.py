r"""The landmark layer that the onboard landmark methods share (:mod:`estimators.retina`, :mod:`estimators.spc`):
neither imports the other; both import this.

* :mod:`.pose` — the a-priori camera pose, the landmark's predicted pixel (Wright et al. 2016, eqs. 1–4), its
  covariance from the pose covariance and the search distance;
* :mod:`.correlation` — the normalised cross-correlation surface over the search area (eq. 9, with the square
  root that makes it a correlation coefficient; Lewis 1995 by FFT);
* :mod:`.peaks` — sub-pixel peak finders on that surface (the paper's 3×3 step, parabola, quadric, Gaussian,
  2-D Gaussian, upsampled) and the pixel-locking curve;
* :mod:`.measurement` — one landmark's measurement (predicted pixel, shift, score, :mod:`estimators.flags` bits)
  and the frame's final output phase (outlier flags against the median shift).

References
----------
C. A. Wright, J. Van Eepoel, A. Liounis, M. Shoemaker, K. DeWeese, K. Getzandanner, "Relative Terrain Imaging
Navigation (RETINA) Tool for the Asteroid Redirect Robotic Mission (ARRM)", NASA Goddard Space Flight Center,
2016 (a technical report; it has no DOI).

J. P. Lewis, "Fast normalized cross-correlation", Vision Interface, Vol. 10, 1995, pp. 120–123 (no DOI).
"""

from estimators.landmarks.measurement import LandmarkMeasurement, facing_flags, final_output_phase
from estimators.landmarks.pose import CameraPoseEstimate, pixel_covariance, project_point, search_radius_px

__all__ = ["CameraPoseEstimate", "LandmarkMeasurement", "facing_flags", "final_output_phase", "pixel_covariance",
           "project_point", "search_radius_px"]
