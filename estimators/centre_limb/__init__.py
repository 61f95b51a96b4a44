"""Centre finding and limb (horizon) navigation of a resolved body: the lab's own onboard-style methods.

Description
-----------
Given an image, the believed camera model, the a-priori camera pose and Sun direction (body frame) and the body's
ellipsoid, each method returns the projected body centre (px) — the line-of-sight observable — with its covariance,
and what else it measures (limb ellipse, limb points, camera-to-body vector and range), or a reason for no result:

- :mod:`.centroid`: (a) intensity centroid with a phase correction (:mod:`.phase`: the centre-of-brightness offset of
  a Lambert or Lommel–Seeliger sphere, eqs. 5–7), eqs. 8–12.
- :mod:`.limb_scan`: sub-pixel edge points along rays from the a-priori centre, lit limb only (eqs. 13–14).
- :mod:`.ellipse_fit`: (b) limb scan + direct least-squares ellipse fit (Fitzgibbon, Pilu & Fisher 1999) or
  ``cv2.fitEllipse``, the fitted conic turned into the body's position (eqs. 19–20).
- :mod:`.horizon`: (c) Christian & Robinson's non-iterative horizon-based OpNav (Cholesky factorisation), eqs. 15–18.
- :mod:`.blob`: an Otsu blob's centroid and an ellipse fitted to its outline, in a window about the predicted
  centre (the analytic proving scene's smoke-test methods).
- :mod:`.common`: the a-priori geometry (the limb cone of :mod:`renderlab.geometry.conic`), the result, the reasons.

Self-contained: numpy, scipy, OpenCV and ``renderlab.geometry`` only. Pixels in the lab's convention ((0, 0) the
centre of the top-left pixel); fits in *ideal pixels* (``K x / z``, the camera's distortion removed).

Tuning
------
Each method's options dataclass (``CentroidOptions``, ``EllipseOptions``, ``HorizonOptions``, with
``LimbScanOptions`` inside the last two) and its module's Tuning table.

Use
---
::

    from estimators.centre_limb import HorizonOpNav, IntensityCentroid, LimbEllipse
    for method in (IntensityCentroid(), LimbEllipse(), HorizonOpNav()):
        est = method.measure(frame)          # frame: image, valid, camera, pose, sun_body, body (see .common)
        print(method.name, est.reason, est.centre_s, est.centre_l, est.r_cam_m)

The lab wraps them as centre/limb methods of ``renderlab.contracts.centre_limb`` in
``renderlab.measurement.centre_limb_methods``.

References
----------
J. A. Christian and S. B. Robinson, "Noniterative horizon-based optical navigation by Cholesky factorization",
J. Guidance, Control, and Dynamics 39(12), 2016, doi:10.2514/1.G000539.

J. A. Christian, "Accurate planetary limb localization for image-based spacecraft navigation", J. Spacecraft and
Rockets 54(3), 2017, doi:10.2514/1.A33692.

A. Fitzgibbon, M. Pilu and R. B. Fisher, "Direct least square fitting of ellipses", IEEE TPAMI 21(5), 1999,
doi:10.1109/34.765658; R. Halíř and J. Flusser, "Numerically stable direct least squares fitting of ellipses",
WSCG 1998 (no DOI).
"""

from .centroid import CentroidOptions, IntensityCentroid
from .common import Estimate
from .ellipse_fit import EllipseOptions, LimbEllipse, fit_ellipse_direct
from .horizon import HorizonOpNav, HorizonOptions
from .limb_scan import LimbScanOptions

__all__ = ["CentroidOptions", "EllipseOptions", "Estimate", "HorizonOpNav", "HorizonOptions", "IntensityCentroid",
           "LimbEllipse", "LimbScanOptions", "fit_ellipse_direct"]
