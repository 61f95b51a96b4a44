"""Conformance harness of the centre/limb kind, and the exact synthetic body image it uses.

:func:`synthetic_body_image` ray-casts an ellipsoid through each pixel, two levels deep (``coarse``² rays per pixel,
``fine``² in the pixels the limb crosses), without a renderer and without the conic geometry the truth and the methods
use: a ray ``o + t d`` meets ``(p − q)ᵀA(p − q) = 1`` where the quadratic's discriminant is ≥ 0. Each pixel is the
mean over its rays of ``value`` (uniform disc) or of ``value·max(n·ŝ, 0)`` (Lambert shading), plus ``background``.

:func:`check_centre_limb_method` runs a method through the rules of :mod:`renderlab.contracts.centre_limb` and returns
one line per failure (empty: conforms):

(a) on the exact uniform disc of a sphere 5° off the boresight at zero phase, seen from an a-priori pose 0.05 %
    off in position, the centre error ``e`` (px) is within the method's **own claimed** uncertainty along it plus a
    floor, ``|e| ≤ 3·√(êᵀ C ê) + centre_tol_px`` (C its ``cov_centre_px2``, NaN counted as 0; floor 0.05 px: the
    disc's own rendering is exact to ~1e-3 px), and, when the method gives a range, ``|Δρ| ≤ 3·√(r̂ᵀ P r̂) +
    range_tol·ρ`` (P its ``cov_r_cam_m2``; floor 0.1 %). A method is judged against what it claims: a wrong
    estimate with an honest covariance passes, a good one with an over-confident covariance fails;
(b) a body behind the camera gives no result with a reason other than ``ok``; every reason is a
    :class:`~renderlab.contracts.centre_limb.CentreLimbReason` value (never empty or NaN);
(c) the inputs are not modified; (d) the same inputs give bit-identical results (``t_ms`` excepted).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.spatial.transform import Rotation

from renderlab.contracts.centre_limb import BodyModel, CentreLimbFrame, CentreLimbReason
from renderlab.contracts.landmark import CameraPose
from renderlab.geometry.camera import CameraModel


def _hits(cam, R_body_from_cam, o, A, sl, sun) -> np.ndarray:
    """Per ray through pixel point ``sl`` (n, 2): 0 (miss), 1 (uniform) or the Lambert μ₀ (``sun`` given)."""
    d = cam.unproject(sl) @ np.asarray(R_body_from_cam, float).T
    a = np.einsum("ij,jk,ik->i", d, A, d)
    b = d @ (A @ o)
    c = o @ A @ o - 1.0
    disc = b * b - a * c
    t = (-b - np.sqrt(np.maximum(disc, 0.0))) / a
    hit = (disc >= 0) & (t > 0)
    if sun is None:
        return hit.astype(float)
    n = (o + t[:, None] * d) @ A
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return np.where(hit, np.maximum(n @ sun, 0.0), 0.0)


def _sub(n: int) -> np.ndarray:
    g = (np.arange(n) + 0.5) / n - 0.5
    return np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)


def synthetic_body_image(cam: CameraModel, R_body_from_cam, position_m, semi_axes_m, *, sun_body=None,
                         value: float = 1000.0, background: float = 10.0, coarse: int = 4,
                         fine: int = 32) -> np.ndarray:
    """The exact image of an ellipsoid centred at the body origin, principal axes along the body axes (module
    docstring); ``sun_body`` None: a uniform disc."""
    A = np.diag(1.0 / np.asarray(semi_axes_m, float) ** 2)
    o = np.asarray(position_m, float)
    sun = None if sun_body is None else np.asarray(sun_body, float) / np.linalg.norm(sun_body)
    grid = cam.pixel_grid().reshape(-1, 2)
    sc, sf = _sub(coarse), _sub(fine)
    v = _hits(cam, R_body_from_cam, o, A, (grid[:, None, :] + sc[None]).reshape(-1, 2), sun)
    v = v.reshape(len(grid), len(sc))
    hit = v > 0
    from scipy.ndimage import binary_dilation

    em = binary_dilation((hit.any(1) & ~hit.all(1)).reshape(cam.height, cam.width))  # the limb's pixels and theirs
    img = v.mean(1)
    idx = np.nonzero(em.ravel())[0]
    for k in range(0, len(idx), 256):
        part = idx[k:k + 256]
        pts = (grid[part][:, None, :] + sf[None]).reshape(-1, 2)
        img[part] = _hits(cam, R_body_from_cam, o, A, pts, sun).reshape(len(part), len(sf)).mean(1)
    return (background + value * img).reshape(cam.height, cam.width)


def disc_case(offset_deg=(4.0, -3.0), range_radii: float = 9.0, width: int = 160, fx: float = 400.0):
    """(true pose, a-priori frame, true projected centre (2,), true range m) of the harness's synthetic disc."""
    R_m = 1000.0
    cam = CameraModel(width=width, height=width, fx=fx, fy=fx, cx=(width - 1) / 2, cy=(width - 1) / 2)
    d = np.array([np.tan(np.radians(offset_deg[0])), np.tan(np.radians(offset_deg[1])), 1.0])
    d /= np.linalg.norm(d)
    rng = range_radii * R_m
    R_bc = Rotation.from_euler("xyz", [20.0, -35.0, 50.0], degrees=True).as_matrix()  # R_body_from_cam
    position = -rng * (R_bc @ d)  # the body centre at the body origin, seen along d
    image = synthetic_body_image(cam, R_bc, position, (R_m, R_m, R_m))
    sun = position / rng  # zero phase: the Sun behind the camera
    apriori = CameraPose(R_body_from_cam=R_bc, position_m=position + 5e-4 * rng * (R_bc @ [1.0, -0.5, 0.0]))
    frame = CentreLimbFrame(image=image, valid=None, camera=cam, pose=apriori, sun_body=sun,
                            body=BodyModel(semi_axes_m=np.full(3, R_m)), index=0, seed=0)
    return cam.project(d * rng), rng, frame


def _same(a, b) -> bool:
    for f in dataclasses.fields(a):
        if f.name == "t_ms":
            continue
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
            if not np.array_equal(np.asarray(x), np.asarray(y), equal_nan=True):
                return False
        elif isinstance(x, float) and np.isnan(x):
            if not (isinstance(y, float) and np.isnan(y)):
                return False
        elif f.name != "extra" and x != y:
            return False
    return True


def _sigma_along(cov, direction) -> float:
    """The claimed standard deviation along ``direction`` (0 where the covariance is missing or not finite)."""
    d = np.asarray(direction, float)
    n = float(np.linalg.norm(d))
    c = np.asarray(cov, float)
    if n == 0.0 or not np.all(np.isfinite(c)) or not np.all(np.isfinite(d)):
        return 0.0
    return float(np.sqrt(max(d @ c @ d / (n * n), 0.0)))


def _measure(method, frame, name: str, fails: list):
    """``method.measure(frame)`` checked against rule 1 (a failure is reported, the result kept or None)."""
    try:
        res = method.measure(frame)
    except Exception as exc:  # noqa: BLE001 - a method that raises breaks the contract: report it
        fails.append(f"(b) {name}: raised {type(exc).__name__}: {exc} (give a reason instead)")
        return None
    try:
        res.check(f"{name}: ")
    except (ValueError, AttributeError, TypeError) as exc:
        fails.append(f"(b) {name}: rule 1 (reason with every missing result, ok with every result): {exc}")
    return res


def check_centre_limb_method(factory, *, centre_tol_px: float = 0.05, range_tol: float = 1e-3) -> list[str]:
    """Rules (a)–(d) of the module docstring for the method ``factory()`` makes; one line per failure."""
    method = factory()
    name = getattr(method, "name", type(method).__name__)
    fails: list[str] = []
    truth, rng, frame = disc_case()
    saved = (frame.image.copy(), frame.pose.R_body_from_cam.copy(), frame.pose.position_m.copy(),
             frame.sun_body.copy(), frame.body.semi_axes_m.copy())
    res, res2 = _measure(method, frame, name, fails), _measure(method, frame, name, fails)
    if res is None or res2 is None:
        return fails
    if not res.has_result:
        fails.append(f"(a) {name}: no result on the synthetic disc ({res.reason}: {res.diagnostics})")
    else:
        e = np.array([res.centre_s - truth[0], res.centre_l - truth[1]])
        err, lim = float(np.hypot(*e)), centre_tol_px + 3.0 * _sigma_along(res.cov_centre_px2, e)
        if not err <= lim:
            fails.append(f"(a) {name}: centre {err:.4f} px from the truth (> 3σ claimed + {centre_tol_px} px = "
                         f"{lim:.4f})")
        if np.isfinite(res.range_m):
            d_rho = res.range_m - rng
            lim = range_tol * rng + 3.0 * _sigma_along(res.cov_r_cam_m2, res.r_cam_m)
            if not abs(d_rho) <= lim:
                fails.append(f"(a) {name}: range {d_rho / rng:+.2e} relative error (> 3σ claimed + {range_tol} = "
                             f"{lim / rng:.2e})")
    now = (frame.image, frame.pose.R_body_from_cam, frame.pose.position_m, frame.sun_body, frame.body.semi_axes_m)
    if not all(np.array_equal(a, b) for a, b in zip(saved, now)):
        fails.append(f"(c) {name}: modified its inputs")
    if not _same(res, res2):
        fails.append(f"(d) {name}: two runs on the same inputs differ")
    back = _measure(method, _looking_away(frame), name, fails)
    if back is not None and (back.has_result or back.reason == CentreLimbReason.OK.value):
        fails.append(f"(b) {name}: a body behind the camera gave reason {back.reason!r}, has_result={back.has_result}")
    return fails


def _looking_away(frame: CentreLimbFrame) -> CentreLimbFrame:
    """The frame with the camera turned 180° about its y axis (the body behind it)."""
    flip = np.diag([-1.0, 1.0, -1.0])
    return dataclasses.replace(frame, pose=CameraPose(R_body_from_cam=frame.pose.R_body_from_cam @ flip,
                                                       position_m=frame.pose.position_m))
