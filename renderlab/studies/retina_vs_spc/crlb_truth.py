"""The registration CRLB of a landmark on the continuous truth, over exactly the estimator's pixels: the truth
rendered again at :data:`FINE_K` × FINE_K sub-pixels (:func:`renderlab.campaign.crlb.fine_truth_dict`) and
:func:`renderlab.campaign.crlb.footprint_bound` over Retina's template footprint at the true pose
(:func:`maplet_footprint`); why, and which bound the published tables carry: ``docs/retina_vs_spc.md``.
"""

from __future__ import annotations

import numpy as np

from estimators.retina import CameraPoseEstimate, TemplateOptions, build_mesh, render_template
from renderlab.campaign.crlb import fine_truth_dict as _fine
from renderlab.campaign.crlb import footprint_bound, sigma_or_nan  # noqa: F401  (the study's bound, re-exported)
from renderlab.geometry.camera import CameraModel
from renderlab.geometry.rotations import rotation_from_quat_xyzw

#: sub-pixels per pixel (each axis) and samples per sub-pixel of the campaigns' fine truth render: one 32-spp render's
#: bound is within 0.994–1.005 (p5–p95) of the cross-product of two (``investigations/error_budget/crlb_continuous.md``)
FINE_K, FINE_SPP = 4, 32


def fine_truth_dict(truth: dict, k: int = FINE_K, spp: int | None = FINE_SPP) -> dict:
    """:func:`renderlab.campaign.crlb.fine_truth_dict` at the study's sub-pixels and samples."""
    return _fine(truth, k, spp)


def true_template(record: dict, maplet, L_table: tuple, supersample: int = 3):
    """(Retina's template of ``maplet`` at the frame record's true camera, pose and Sun, the camera)."""
    R = rotation_from_quat_xyzw(record["pose"]["quat_render_from_cam_xyzw"], "pose").as_matrix()
    sun = np.asarray(record["sun"]["direction_render"], float)
    cam = CameraModel.from_dict(record["camera"])
    return render_template(build_mesh(maplet), cam, CameraPoseEstimate(R, np.asarray(record["pose"]["position_m"], float)),
                           sun / np.linalg.norm(sun), TemplateOptions(supersample=supersample, L_table=tuple(L_table))), cam


def maplet_footprint(record: dict, maplet, L_table: tuple, supersample: int = 3):
    """The pixels Retina's template of ``maplet`` covers at the frame's true pose, inside the image (what the
    estimators read) → (l0, s0, valid (h, w)), or None where no template can be made or none of it is inside."""
    tpl, cam = true_template(record, maplet, L_table, supersample)
    if tpl is None:
        return None
    h, w = tpl.valid.shape
    r0, c0 = max(-tpl.l0, 0), max(-tpl.s0, 0)
    r1, c1 = min(h, cam.height - tpl.l0), min(w, cam.width - tpl.s0)
    if r1 <= r0 or c1 <= c0:
        return None
    return int(tpl.l0 + r0), int(tpl.s0 + c0), np.asarray(tpl.valid, bool)[r0:r1, c0:c1]
