"""Camera poses of the ``planet_approach`` path, and the render origin the float32 scene is built around.

``planet_approach`` (:class:`~renderlab.worlds.planet.config.PlanetApproachTrajectory`): frame k has range ρₖ and phase
αₖ (linear in k); the camera sits at ``centre + ρₖ·Rot(k̂, αₖ)·ŝ`` with ``ŝ`` the unit vector toward the sun and ``k̂``
the unit ``ŝ × up`` turned by ``phase_plane_deg`` about ``ŝ``, so that the Sun–centre–camera angle is αₖ. The boresight
points at the centre, then turns so the centre appears at the angles ``offset_deg`` from the boresight.

Render origin (:func:`render_origin`): the backends build float32 scenes around ``SceneDescription.origin_m``. A point
at distance ``m`` from the origin carries ``ε·m`` of rounding (ε = 2⁻²⁴); seen from ``d`` with a focal length ``f`` px
that is ``ε·m·f/d`` px. Per frame ``m`` is the larger of the camera's and the looked-at point's distance from the
origin, ``d`` the camera's distance from the looked-at point (the boresight's hit on the body, else the boresight
point nearest the centre). With the origin at the body centre the bound is ``≈ ε·f`` from afar but grows as
``ε·f·R/h`` at a height ``h ≪ R``; when it exceeds ``origin_tolerance_px`` the origin moves to the looked-at point of
the worst frame.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from renderlab.dynamics.camera_paths import CameraPose
from renderlab.errors import UserError
from renderlab.geometry.rotations import look_at

EPS32 = 2.0 ** -24


def _lin(a: float, b: float | None, n: int) -> np.ndarray:
    b = a if b is None else b
    return np.full(1, a) if n == 1 else np.linspace(a, b, n)


def approach_poses(traj, sun_direction, centre_m) -> list[CameraPose]:
    """Camera poses of a ``planet_approach`` trajectory (module docstring) in the render frame."""
    s = np.asarray(sun_direction, float)
    s = s / np.linalg.norm(s)
    up = np.asarray(traj.up, float)
    k = np.cross(s, up)
    if np.linalg.norm(k) < 1e-9 * np.linalg.norm(up):
        k = np.cross(s, [1.0, 0.0, 0.0] if abs(s[0]) < 0.9 else [0.0, 1.0, 0.0])
    k = Rotation.from_rotvec(np.radians(traj.phase_plane_deg) * s).apply(k / np.linalg.norm(k))
    ranges = _lin(traj.range_start_m, traj.range_end_m, traj.frames)
    phases = np.radians(_lin(traj.phase_start_deg, traj.phase_end_deg, traj.frames))
    ox, oy = np.radians(traj.offset_deg)
    d_cam = np.array([np.tan(ox), np.tan(oy), 1.0])
    align = Rotation.align_vectors([[0.0, 0.0, 1.0]], [d_cam / np.linalg.norm(d_cam)])[0]  # centre dir → +z
    poses = []
    for i, (rho, a) in enumerate(zip(ranges, phases)):
        pos = np.asarray(centre_m, float) + rho * Rotation.from_rotvec(a * k).apply(s)
        look_up = up if np.linalg.norm(np.cross(pos - centre_m, up)) > 1e-6 * rho * np.linalg.norm(up) else k
        R = look_at(pos, centre_m, look_up) * align  # R_render_from_cam: the centre at d_cam in the camera
        poses.append(CameraPose(time_s=i * traj.dt_s, position_m=pos, rotation=R))
    return poses


def look_point(position, R_render_from_cam: Rotation, body) -> np.ndarray:
    """Where the boresight meets the body's ellipsoid (nearest hit), else its point nearest the centre."""
    from renderlab.geometry.conic import shape_matrix

    A = shape_matrix(body.semi_axes_m, body.R_render_from_principal)
    o = np.asarray(position, float) - body.centre_m
    d = R_render_from_cam.apply([0.0, 0.0, 1.0])
    a, b, c = d @ A @ d, d @ A @ o, o @ A @ o - 1.0
    disc = b * b - a * c
    if disc >= 0:
        t = (-b - np.sqrt(disc)) / a
        if t > 0:
            return body.centre_m + o + t * d
    return body.centre_m + o + max(-(o @ d), 0.0) * d


def float32_bound_px(spec, body, origin) -> float:
    """The float32 rounding of the frame ``spec`` in pixels at the looked-at point (module docstring)."""
    p = look_point(spec.pose.position_m, spec.pose.rotation, body)
    c = np.asarray(spec.pose.position_m, float)
    m = max(np.linalg.norm(c - origin), np.linalg.norm(p - origin))
    d = max(np.linalg.norm(p - c), 1e-9)
    return float(EPS32 * m * max(spec.camera.fx, spec.camera.fy) / d)


def render_origin(frames, body, tolerance_px: float) -> tuple[np.ndarray, float]:
    """(origin (3,), its worst float32 bound in px): the body centre if its bound is within ``tolerance_px``, else the
    looked-at point of the worst frame."""
    centre = np.asarray(body.centre_m, float)
    if not frames:
        return centre, 0.0
    bounds = [float32_bound_px(f, body, centre) for f in frames]
    worst = int(np.argmax(bounds))
    if bounds[worst] <= tolerance_px:
        return centre, bounds[worst]
    origin = look_point(frames[worst].pose.position_m, frames[worst].pose.rotation, body)
    return origin, max(float32_bound_px(f, body, origin) for f in frames)


def check_frames(frames, body, far_clip_m: float) -> None:
    """One line when a camera is inside the body or the body lies beyond the far clip plane."""
    from renderlab.geometry.conic import shape_matrix

    A = shape_matrix(body.semi_axes_m, body.R_render_from_principal)
    r_max = body.max_radius_m
    for f in frames:
        o = np.asarray(f.pose.position_m, float) - body.centre_m
        if o @ A @ o <= 1.0 or np.linalg.norm(o) <= r_max:
            raise UserError(f"trajectory: frame {f.index} puts the camera inside the body ({np.linalg.norm(o):.6g} m "
                            f"from its centre, radius up to {r_max:.6g} m)")
        if np.linalg.norm(o) + r_max > far_clip_m:
            raise UserError(f"render.far_clip_m ({far_clip_m:.6g} m) cuts the body in frame {f.index}; set it to at "
                            f"least {np.linalg.norm(o) + r_max:.6g} m")
