r"""Pixel-locking curve of the peak finders on Retina-rendered maplets (the textures' curve is
:func:`estimators.landmarks.peaks.pixel_locking_curve`).

A maplet is rendered by Retina's synthetic-image tracer at the true pose of a nadir camera and pasted
into an empty image (valid only where the template is); the a-priori camera is then translated parallel
to the image plane so that the landmark's predicted pixel is off the truth by a known fractional shift
(f, f/2) px. Retina measures it (correlation, eq. 9, and each finder); the bias is the measured shift
minus the realised true shift (truth − prediction, both by eqs. 1–4), averaged over a few maplets.
"""

from __future__ import annotations

import numpy as np

from estimators.landmarks.peaks import FINDERS
from estimators.landmarks.pose import CameraPoseEstimate, project_point
from estimators.retina.landmarks import RetinaOptions, measure_landmark
from estimators.retina.maplet_mesh import build_mesh
from estimators.retina.peak_step import STEPS
from estimators.retina.predict import TemplateOptions, render_template
from renderlab.geometry.camera import CameraModel
from renderlab.geometry.maplet import Maplet


def plain_maplet(n: int = 41, spacing: float = 0.1, seed: int = 5) -> Maplet:
    """A smooth random relief (σ = 0.6 m smoothed over 1.5 cells) with an albedo texture."""
    from scipy.ndimage import gaussian_filter

    rng = np.random.default_rng(seed)
    h = gaussian_filter(rng.normal(0, 0.6, (n, n)), 1.5)
    a = 1 + 0.3 * gaussian_filter(rng.normal(size=(n, n)), 1.0) / 0.28
    return Maplet(3, np.array([0.5, -0.2, 0.0]), np.eye(3), spacing, h, np.clip(a, 0.3, 3))


def rendered_locking_curve(fractions, methods=tuple(FINDERS), seeds=(5, 6, 7), search_px: int = 3,
                           template: TemplateOptions = TemplateOptions()):
    """Bias of each finder (or step of :data:`~.peak_step.STEPS`) vs a known fractional shift (f, f/2) of a
    Retina-rendered maplet.

    Returns
    -------
    dict
        ``{method: (bias_s (F,), bias_l (F,))}``, px, averaged over the maplets of ``seeds``.
    """
    cam = CameraModel.from_dict({"width": 96, "height": 96, "fx": 110.0, "fy": 110.0, "cx": 47.5, "cy": 47.5})
    sun = np.array([0.5, 0.3, 0.8]) / np.linalg.norm([0.5, 0.3, 0.8])
    R = np.diag([1.0, -1.0, -1.0])  # looking straight down: camera +x = maplet +x, +y = maplet −y
    fr = np.asarray(fractions, float)
    out = {m: (np.zeros(len(fr)), np.zeros(len(fr))) for m in methods}
    for seed in seeds:
        M = plain_maplet(seed=seed)
        mesh = build_mesh(M)
        true = CameraPoseEstimate(R, np.array([0.5, -0.2, 10.0]))
        tpl = render_template(mesh, cam, true, sun, template)
        img = np.zeros((cam.height, cam.width))
        valid = np.zeros(img.shape, bool)
        sl = np.s_[tpl.l0:tpl.l0 + tpl.image.shape[0], tpl.s0:tpl.s0 + tpl.image.shape[1]]
        img[sl], valid[sl] = tpl.image, tpl.valid
        truth = project_point(cam, true, M.center_m)
        # pixel motion of the prediction per metre of camera translation along body x and y
        J = np.column_stack([project_point(cam, CameraPoseEstimate(R, true.position_m + e), M.center_m) - truth
                             for e in (np.array([1e-4, 0, 0]), np.array([0, 1e-4, 0]))]) / 1e-4
        for k, f in enumerate(fr):
            dxy = np.linalg.solve(J, -np.array([f, f / 2]))  # prediction = truth − (f, f/2)
            ap = CameraPoseEstimate(R, true.position_m + np.array([dxy[0], dxy[1], 0.0]))
            pred = project_point(cam, ap, M.center_m)
            true_shift = truth - pred
            for m in methods:
                finder, passes, refine = STEPS[m]
                r = measure_landmark(img, mesh, cam, ap, sun, search_px,
                                     RetinaOptions(template=template, peak=finder, recentre_passes=passes,
                                                   refine=refine),
                                     image_valid=valid)
                if not r.has_result:
                    raise RuntimeError(f"no result for finder {m} at shift {f} (flags {r.flags})")
                out[m][0][k] += (r.ds - true_shift[0]) / len(seeds)
                out[m][1][k] += (r.dl - true_shift[1]) / len(seeds)
    return out
