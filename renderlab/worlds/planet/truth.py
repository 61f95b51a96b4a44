"""``centre_truth`` rows of the planet world: the body's centre and true limb conic in each frame, from the true pose.

Geometry (:mod:`renderlab.geometry.conic`): with ``R`` = R_render_from_cam, the camera at ``c`` and the truth ellipsoid
(centre ``q``, shape matrix ``A`` in the render frame), the camera-frame centre is ``r = Rᵀ(q − c)`` and shape matrix
``Rᵀ A R``; the limb cone ``M`` (eq. 1 there) and, through the camera's pinhole map ``K``, the limb conic ``C``
(eq. 2), whose centre, semi-axes and angle (eqs. 3–4) fill the ``limb_*`` columns. The projected centre uses the full
camera model (distortion included); the conic is that of the distortion-free pinhole ``K`` (a distorted limb is no
conic), the frame the onboard methods fit in after undistorting. Columns:
:data:`renderlab.contracts.schemas.CENTRE_TRUTH`.
A body behind the camera, or one whose limb cone crosses the camera plane (no ellipse in the image), has NaN limb
columns and ``limb_in_image`` false.
"""

from __future__ import annotations

import math

import numpy as np

from renderlab.geometry.conic import cone_to_pixels, ellipse_params, limb_cone, shape_matrix

_NAN_LIMB = {"limb_centre_s": math.nan, "limb_centre_l": math.nan, "limb_a_px": math.nan, "limb_b_px": math.nan,
             "limb_angle_rad": math.nan, "apparent_radius_px": math.nan}


def limb_in_image(camera, centre, a: float, b: float, angle: float) -> bool:
    """True when the whole ellipse lies inside the image (half-open pixel bounds, as ``CameraModel.in_image``)."""
    c, s = math.cos(angle), math.sin(angle)
    hx, hy = math.hypot(a * c, b * s), math.hypot(a * s, b * c)
    return bool(centre[0] - hx >= -0.5 and centre[0] + hx < camera.width - 0.5
                and centre[1] - hy >= -0.5 and centre[1] + hy < camera.height - 0.5)


def centre_truth_row(spec, body) -> dict:
    """One ``centre_truth`` row for the frame ``spec`` (a :class:`~renderlab.render.scene.FrameSpec`) and ``body``
    (a :class:`~renderlab.worlds.planet.body.PlanetBody`)."""
    R = spec.pose.rotation.as_matrix()
    c = np.asarray(spec.pose.position_m, float)
    r = R.T @ (np.asarray(body.centre_m, float) - c)
    rho = float(np.linalg.norm(r))
    A_cam = R.T @ shape_matrix(body.semi_axes_m, body.R_render_from_principal) @ R
    M = limb_cone(A_cam, r)
    M = M / np.linalg.norm(M)
    cam = spec.camera
    sl = cam.project(r)
    sun = np.asarray(spec.sun.direction_render, float)
    view = (c - body.centre_m) / rho
    row = {"frame": int(spec.index), "time_s": float(spec.pose.time_s), "body": body.spec.name,
           "centre_s": float(sl[0]), "centre_l": float(sl[1]), **_NAN_LIMB, "range_m": rho,
           "los_cam_x": float(r[0] / rho), "los_cam_y": float(r[1] / rho), "los_cam_z": float(r[2] / rho),
           "phase_deg": math.degrees(math.acos(float(np.clip(view @ sun / np.linalg.norm(sun), -1.0, 1.0)))),
           **{f"cone_{k}": float(M[i, j]) for k, (i, j) in
              {"xx": (0, 0), "xy": (0, 1), "xz": (0, 2), "yy": (1, 1), "yz": (1, 2), "zz": (2, 2)}.items()},
           "limb_in_image": False, "limb_model": body.limb_model}
    ell = ellipse_params(cone_to_pixels(M, cam.K_matrix)) if r[2] > 0 else None
    if ell is not None:
        u0, a, b, angle = ell
        row.update(limb_centre_s=float(u0[0]), limb_centre_l=float(u0[1]), limb_a_px=a, limb_b_px=b,
                   limb_angle_rad=angle, apparent_radius_px=math.sqrt(a * b),
                   limb_in_image=limb_in_image(cam, u0, a, b, angle))
    return row
