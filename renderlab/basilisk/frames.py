"""Basilisk's attitude and camera conventions turned into the lab's camera pose and camera model (numpy only).

Basilisk (Schaub & Junkins, *Analytical Mechanics of Space Systems*, 4th ed., AIAA 2018, doi:10.2514/4.105210):

* an MRP set ``σ_BN`` gives the direction cosine matrix ``[BN] = C(σ)``, the matrix that maps a vector's inertial
  components to its body components (``v_B = [BN] v_N``): ``C = I + (8[σ̃]² − 4(1 − σ²)[σ̃]) / (1 + σ²)²``;
  in the lab's naming (``p_A = R_A_from_B · p_B``) ``[BN]`` is ``R_B_from_N``;
* Euler parameters (quaternions) are scalar first, ``β = (β₀, β₁, β₂, β₃)``, and describe the same ``[BN]``;
  ``σ = (β₁, β₂, β₃)/(1 + β₀)``; ``|σ| ≤ 1`` is the short rotation, ``−σ/σ²`` its shadow set;
* the camera is mounted by ``σ_CB`` (``[CB] = C(σ_CB)``) at ``cameraPos_B`` (m, body frame); the spacecraft state
  message gives ``r_BN_N`` and ``σ_BN``; a planet's SPICE state message ``PositionVector`` (``r_PN_N``) and
  ``J20002Pfix`` (``[PN]``, inertial → planet-fixed components).

The camera frame C is the lab's: +z the boresight, +x toward increasing sample (column), +y toward increasing line
(row); ``pixelLineConverter`` forms the line of sight as ``((u − u₀)·X, (v − v₀)·Y, 1)`` in C. A planet world's render
frame is the planet-fixed frame P with its origin at the planet's centre, so the lab pose of the camera is

    position_m        = [PN] (r_BN_N + [BN]ᵀ cameraPos_B − r_PN_N)
    R_render_from_cam = [PN] [BN]ᵀ [CB]ᵀ

Camera model (``CameraConfigMsgPayload``): ``fieldOfView`` is edge to edge along the camera's y axis (the image
height), square pixels, so ``fx = fy = (H/2) / tan(fov/2)``; the principal point is the centre of the detector,
``(W/2, H/2)`` with pixel *corners* at integers (as a Unity/Vizard render), which is ``cx = (W − 1)/2``,
``cy = (H − 1)/2`` in the lab's pixel-centre coordinates. ``pixelLineConverter`` re-centres a pixel ``u`` as
``u − W/2 + 0.5``: the same principal point when ``u`` is in pixel-centre coordinates.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial.transform import Rotation

from renderlab.dynamics.camera_paths import CameraPose
from renderlab.errors import UserError
from renderlab.geometry.camera import CameraModel


def vec3(v, name: str) -> np.ndarray:
    """``v`` as a finite float64 3-vector, or a one-line error naming it."""
    try:
        a = np.asarray(v, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise UserError(f"{name} must be 3 numbers") from None
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise UserError(f"{name} must be 3 finite numbers, got shape {a.shape}")
    return a


def _dcm(m, name: str) -> np.ndarray:
    try:
        a = np.asarray(m, dtype=np.float64).reshape(3, 3)
    except (TypeError, ValueError):
        raise UserError(f"{name} must be a 3x3 direction cosine matrix") from None
    if not np.all(np.isfinite(a)) or not np.allclose(a @ a.T, np.eye(3), atol=1e-9) or np.linalg.det(a) < 0:
        raise UserError(f"{name} must be a proper orthonormal 3x3 matrix (a direction cosine matrix)")
    return a


def skew(v) -> np.ndarray:
    """The cross-product matrix ``[ṽ]`` with ``[ṽ] w = v × w``."""
    x, y, z = v
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def mrp_to_dcm(sigma) -> np.ndarray:
    """``[BN] = C(σ)`` of an MRP set (module docstring)."""
    s = vec3(sigma, "sigma")
    s2 = float(s @ s)
    S = skew(s)
    return np.eye(3) + (8.0 * S @ S - 4.0 * (1.0 - s2) * S) / (1.0 + s2) ** 2


def mrp_to_quat_wxyz(sigma) -> np.ndarray:
    """Euler parameters ``(β₀, β₁, β₂, β₃)`` (scalar first) of an MRP set: ``β₀ = (1 − σ²)/(1 + σ²)``,
    ``β_i = 2σ_i/(1 + σ²)``."""
    s = vec3(sigma, "sigma")
    s2 = float(s @ s)
    return np.concatenate([[(1.0 - s2) / (1.0 + s2)], 2.0 * s / (1.0 + s2)])


def quat_wxyz_to_mrp(beta) -> np.ndarray:
    """The short MRP set (``|σ| ≤ 1``) of Euler parameters ``(β₀, β₁, β₂, β₃)`` (any norm, any sign)."""
    b = np.asarray(beta, dtype=np.float64).reshape(-1)
    n = float(np.linalg.norm(b)) if b.shape == (4,) else 0.0
    if not np.isfinite(n) or n < 1e-12:
        raise UserError("Euler parameters must be 4 finite numbers, not all zero")
    b = b / n
    if b[0] < 0:
        b = -b
    return b[1:] / (1.0 + b[0])


def dcm_to_quat_wxyz(C) -> np.ndarray:
    """Euler parameters (β₀ ≥ 0) of a DCM ``[BN]`` (Sheppard's method: the largest component first)."""
    C = _dcm(C, "dcm")
    tr = np.trace(C)
    b2 = 0.25 * np.array([1.0 + tr, 1.0 + 2 * C[0, 0] - tr, 1.0 + 2 * C[1, 1] - tr, 1.0 + 2 * C[2, 2] - tr])
    k = int(np.argmax(b2))
    b = np.empty(4)
    b[k] = math.sqrt(b2[k])
    off = {  # 4 β_i β_j from the off-diagonal terms
        (0, 1): C[1, 2] - C[2, 1], (0, 2): C[2, 0] - C[0, 2], (0, 3): C[0, 1] - C[1, 0],
        (1, 2): C[0, 1] + C[1, 0], (1, 3): C[2, 0] + C[0, 2], (2, 3): C[1, 2] + C[2, 1],
    }
    for j in range(4):
        if j != k:
            b[j] = off[(min(j, k), max(j, k))] / (4.0 * b[k])
    return -b if b[0] < 0 else b


def dcm_to_mrp(C) -> np.ndarray:
    """The short MRP set (``|σ| ≤ 1``) of a DCM ``[BN]``."""
    return quat_wxyz_to_mrp(dcm_to_quat_wxyz(C))


def camera_model(field_of_view: float, resolution) -> CameraModel:
    """The lab's pinhole of a Basilisk camera: ``fieldOfView`` (rad, edge to edge along y), ``resolution``
    (width, height) px; square pixels, principal point at the detector's centre (module docstring)."""
    fov = float(field_of_view)
    if not (math.isfinite(fov) and 0.0 < fov < math.pi):
        raise UserError(f"fieldOfView must be in (0, pi) rad, got {str(field_of_view)[:40]}")
    try:
        w, h = (int(v) for v in resolution)
    except (TypeError, ValueError):
        raise UserError("resolution must be (width, height) in pixels") from None
    if not (0 < w <= 16384 and 0 < h <= 16384):
        raise UserError(f"resolution must be two integers in 1..16384, got {w}, {h}")
    f = (h / 2.0) / math.tan(fov / 2.0)
    return CameraModel(width=w, height=h, fx=f, fy=f, cx=(w - 1) / 2.0, cy=(h - 1) / 2.0)


def camera_pose(r_BN_N, sigma_BN, *, sigma_CB=(0.0, 0.0, 0.0), cameraPos_B=(0.0, 0.0, 0.0),
                r_PN_N=(0.0, 0.0, 0.0), dcm_PN=None, time_s: float = 0.0) -> CameraPose:
    """The lab's :class:`CameraPose` in the planet-fixed render frame from Basilisk's states (module docstring).

    Parameters
    ----------
    r_BN_N, sigma_BN : 3-vectors
        Spacecraft body origin (m, inertial) and attitude MRPs (``SCStatesMsgPayload``).
    sigma_CB, cameraPos_B : 3-vectors
        Camera mount: MRPs of the camera frame relative to the body, camera position in the body frame (m).
    r_PN_N : 3-vector
        Planet centre (m, inertial: ``SpicePlanetStateMsgPayload.PositionVector``).
    dcm_PN : (3, 3), optional
        ``J20002Pfix`` (inertial → planet-fixed components); None: identity.
    time_s : float
        Time of the pose (s).
    """
    BN = mrp_to_dcm(sigma_BN)
    CB = mrp_to_dcm(sigma_CB)
    PN = np.eye(3) if dcm_PN is None else _dcm(dcm_PN, "J20002Pfix")
    c_N = vec3(r_BN_N, "r_BN_N") + BN.T @ vec3(cameraPos_B, "cameraPos_B") - vec3(r_PN_N, "PositionVector")
    R = PN @ BN.T @ CB.T
    return CameraPose(float(time_s), PN @ c_N, Rotation.from_matrix(R))


def sun_direction(r_SN_N, r_PN_N, dcm_PN=None) -> np.ndarray:
    """Unit vector from the planet toward the sun in the planet-fixed frame (``[PN](r_SN_N − r_PN_N)``)."""
    d = vec3(r_SN_N, "sun PositionVector") - vec3(r_PN_N, "PositionVector")
    n = float(np.linalg.norm(d))
    if n <= 0.0:
        raise UserError("the sun and the planet are at the same position")
    PN = np.eye(3) if dcm_PN is None else _dcm(dcm_PN, "J20002Pfix")
    return PN @ (d / n)
