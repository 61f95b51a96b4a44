r"""Camera models: pinhole + lens distortion + the Retina pixel map, with an exact inverse.

Theory (Wright et al., "Retina", eqs. 1-4). A point :math:`\mathbf{x}_B` in frame B is first expressed in
the camera frame, :math:`\mathbf{x}_C = \mathbf{T}_C^B(\mathbf{x}_B - \mathbf{t}_B)` (eqs. 1-2, see
:func:`renderlab.geometry.rotations.to_camera_frame`). The lab camera frame has +z along the boresight,
+x toward increasing sample (right) and +y toward increasing line (down). This module then maps

1. gnomonic projection (eq. 3) to normalized coordinates :math:`\mathbf{u} = (x_C/z_C,\ y_C/z_C)`,
   focal-plane coordinates in units of the focal length. The paper's eq. 3 carries a minus sign because
   it images onto the physical plane behind the pinhole; the lab uses the positive (virtual) image plane
   in front of it, so the sign flip is absorbed in the frame convention (+x right, +y down) and no minus
   sign appears here;
2. a distortion model :math:`\mathbf{u}_d = D(\mathbf{u})` (none, Brown, Owen, OpenCV's full model or
   the OpenCV fisheye; see :mod:`renderlab.geometry.distortion`);
3. the pixel map (eq. 4) with a full 2x2 matrix,
   :math:`s = f_x u_d + \mathrm{skew}\,v_d + c_x`, :math:`l = \mathrm{skew\_yx}\,u_d + f_y v_d + c_y`.
   ``[[fx, skew], [skew_yx, fy]]`` is the paper's K (px/mm) times the focal length (mm), and
   ``(cx, cy) = (s0, l0)``. Pinhole/OpenCV cameras have ``skew_yx = 0``.

Pixel coordinates are (sample, line) = (column, row); pixel centres are at integers and (0, 0) is the
centre of the top-left pixel, so the image spans -0.5 .. W-0.5 in s and -0.5 .. H-0.5 in l.

The inverse (:meth:`CameraModel.unproject`) solves the 2x2 pixel map exactly, inverts the distortion by
Newton's method with the analytic Jacobian, and returns unit rays in the camera frame.
"""

from __future__ import annotations

import functools
import math
import types
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from typing import Any, Literal

import numpy as np

from renderlab.errors import UserError
from renderlab.inputs import PIXEL_MAX, short

from .distortion import MODELS, distort, distortion_jacobian, max_valid_radius, normalize_distortion, undistort

__all__ = ["CameraModel"]

_DICT_KEYS = ("width", "height", "fx", "fy", "cx", "cy", "skew", "skew_yx", "model", "distortion")
_REQUIRED_KEYS = ("width", "height", "fx", "fy", "cx", "cy")


def _is_real(value) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))


def _is_int(value) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))


@dataclass(frozen=True)
class CameraModel:
    """An intrinsic camera model: gnomonic projection, distortion and the 2x2 pixel map (eqs. 3-4).

    Parameters
    ----------
    width, height : int
        Image size in pixels.
    fx, fy : float
        Diagonal of the pixel map, px per unit normalized coordinate (focal length in px).
    cx, cy : float
        Principal point (s0, l0) in px, pixel-centre convention ((0, 0) = centre of the top-left pixel).
    skew : float
        Off-diagonal ``K[0, 1]`` (sample per unit y_d), OpenCV's skew.
    skew_yx : float
        Off-diagonal ``K[1, 0]`` (line per unit x_d), the Retina/Owen ``Kyx`` term; 0 for OpenCV.
    model : {"pinhole", "brown", "owen", "opencv", "kannala_brandt"}
        Distortion model.
    distortion : mapping of str to float
        Coefficients (``brown``: k1 k2 k3 p1 p2; ``owen``: e1..e6 in units of the focal length; ``opencv``:
        k1 k2 p1 p2 k3 k4 k5 k6 s1 s2 s3 s4 tau_x tau_y; ``kannala_brandt``: k1 k2 k3 k4).
        Missing keys are 0; after construction it is a read-only mapping holding every key of the model.

    Raises
    ------
    UserError
        On any invalid field, with a one-line message naming it (``camera.fx must be ...``).
    """

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    skew: float = 0.0
    skew_yx: float = 0.0
    model: Literal["pinhole", "brown", "owen", "opencv", "kannala_brandt"] = "pinhole"
    distortion: Mapping[str, float] = field(default_factory=dict)

    # ------------------------------------------------------------------ construction / validation
    def __post_init__(self) -> None:
        set_ = lambda name, value: object.__setattr__(self, name, value)  # noqa: E731 (frozen)
        for name in ("width", "height"):
            v = getattr(self, name)
            if not _is_int(v) or int(v) <= 0:
                raise UserError(f"camera.{name} must be a positive integer, got {short(v)}")
            set_(name, int(v))
        for name in ("fx", "fy"):
            v = getattr(self, name)
            if not _is_real(v) or not math.isfinite(float(v)) or float(v) <= 0.0:
                raise UserError(f"camera.{name} must be a positive finite number, got {short(v)}")
            if float(v) > PIXEL_MAX:
                raise UserError(f"camera.{name} must be at most {PIXEL_MAX:g} px, got {short(v)}")
            set_(name, float(v))
        for name in ("cx", "cy", "skew", "skew_yx"):
            v = getattr(self, name)
            if not _is_real(v) or not math.isfinite(float(v)) or abs(float(v)) > PIXEL_MAX:
                raise UserError(f"camera.{name} must be a finite number of at most {PIXEL_MAX:g} px in size, got "
                                f"{short(v)}")
            set_(name, float(v))
        if not isinstance(self.model, str) or self.model not in MODELS:
            raise UserError(f"camera.model must be one of {', '.join(repr(m) for m in MODELS)}, got {short(self.model)}")
        coeffs = normalize_distortion(self.model, self.distortion, where="camera")
        set_("distortion", types.MappingProxyType(coeffs))
        det = self.fx * self.fy - self.skew * self.skew_yx
        if not abs(det) > 1e-12 * max(self.fx * self.fy, abs(self.skew * self.skew_yx)):
            raise UserError(
                f"camera pixel map [[fx, skew], [skew_yx, fy]] is singular "
                f"(fx*fy - skew*skew_yx = {det!r}); check camera.skew and camera.skew_yx"
            )

    def __hash__(self) -> int:
        return hash(tuple(getattr(self, f.name) for f in fields(self) if f.name != "distortion")
                    + tuple(self.distortion.items()))

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "CameraModel":
        """Build from the manifest camera dict (see ``docs/architecture.md``; ``skew``, ``skew_yx``, ``model`` and
        ``distortion`` are optional). Unknown or missing keys raise :class:`UserError`."""
        if not isinstance(d, Mapping):
            raise UserError(f"camera must be a table of camera parameters, got {type(d).__name__}")
        unknown = [k for k in d if k not in _DICT_KEYS]
        if unknown:
            raise UserError(f"camera.{unknown[0]}: unknown key (allowed: {', '.join(_DICT_KEYS)})")
        missing = [k for k in _REQUIRED_KEYS if k not in d]
        if missing:
            raise UserError(f"camera.{missing[0]} is missing")
        return cls(**dict(d))

    def to_dict(self) -> dict[str, Any]:
        """The manifest camera dict: plain Python ints, floats, str and a dict of coefficients."""
        return {
            "width": self.width, "height": self.height,
            "fx": self.fx, "fy": self.fy, "cx": self.cx, "cy": self.cy,
            "skew": self.skew, "skew_yx": self.skew_yx,
            "model": self.model, "distortion": dict(self.distortion),
        }

    @classmethod
    def from_fov(
        cls,
        width: int,
        height: int,
        fov_x_deg: float,
        fov_y_deg: float | None = None,
        *,
        cx: float | None = None,
        cy: float | None = None,
        model: str = "pinhole",
        distortion: Mapping[str, float] | None = None,
        skew: float = 0.0,
        skew_yx: float = 0.0,
    ) -> "CameraModel":
        """Camera whose full image width (pixel edges -0.5 .. W-0.5) spans `fov_x_deg`.

        ``fx = (W/2) / tan(fov_x/2)``; ``fy`` from `fov_y_deg` over the height, or ``fy = fx`` (square
        pixels) when it is None. The principal point defaults to the image centre ((W-1)/2, (H-1)/2).
        Distortion does not enter the field-of-view relation.
        """
        def focal(n, fov, name):
            if not _is_real(fov) or not (0.0 < float(fov) < 180.0):
                raise UserError(f"camera.{name} must be in (0, 180) degrees, got {short(fov)}")
            return (n / 2.0) / math.tan(math.radians(float(fov)) / 2.0)

        if not _is_int(width) or width <= 0:
            raise UserError(f"camera.width must be a positive integer, got {short(width)}")
        if not _is_int(height) or height <= 0:
            raise UserError(f"camera.height must be a positive integer, got {short(height)}")
        fx = focal(width, fov_x_deg, "fov_x_deg")
        fy = fx if fov_y_deg is None else focal(height, fov_y_deg, "fov_y_deg")
        return cls(width, height, fx, fy,
                   (width - 1) / 2.0 if cx is None else cx, (height - 1) / 2.0 if cy is None else cy,
                   skew=skew, skew_yx=skew_yx, model=model, distortion=distortion or {})

    @classmethod
    def from_retina(
        cls,
        focal_length_mm: float,
        Kx: float, Kxy: float, Kyx: float, Ky: float,
        s0: float, l0: float,
        width: int, height: int,
        *,
        model: str = "pinhole",
        distortion: Mapping[str, float] | None = None,
    ) -> "CameraModel":
        """Camera from the Retina paper's eq. 4: K in px/mm, focal length in mm, (s0, l0) in px.

        ``fx = f Kx, skew = f Kxy, skew_yx = f Kyx, fy = f Ky, cx = s0, cy = l0``. Distortion
        coefficients must be in normalized units; convert millimetre-based Owen coefficients with
        :func:`renderlab.geometry.distortion.owen_coefficients_from_mm`.
        """
        f = focal_length_mm
        if not _is_real(f) or not math.isfinite(float(f)) or float(f) <= 0.0:
            raise UserError(f"camera.focal_length_mm must be a positive finite number, got {short(f)}")
        f = float(f)
        vals = {"Kx": Kx, "Kxy": Kxy, "Kyx": Kyx, "Ky": Ky}
        for name, v in vals.items():
            if not _is_real(v) or not math.isfinite(float(v)):
                raise UserError(f"camera.{name} must be a finite number, got {short(v)}")
        return cls(width, height, f * float(Kx), f * float(Ky), s0, l0,
                   skew=f * float(Kxy), skew_yx=f * float(Kyx), model=model, distortion=distortion or {})

    # ------------------------------------------------------------------ matrices
    @property
    def K_matrix(self) -> np.ndarray:
        """The 3x3 intrinsic matrix ``[[fx, skew, cx], [skew_yx, fy, cy], [0, 0, 1]]``."""
        return np.array([[self.fx, self.skew, self.cx], [self.skew_yx, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @functools.cached_property
    def max_radius(self) -> float:
        """Undistorted normalized radius |(x/z, y/z)| beyond which the distortion folds over (``inf`` if it
        does not; see :func:`~renderlab.geometry.distortion.max_valid_radius`). :meth:`project` returns NaN
        there and :meth:`unproject` never returns rays there, so both stay on the one-to-one branch."""
        return max_valid_radius(self.model, self.distortion)

    @property
    def _K2(self) -> np.ndarray:
        return np.array([[self.fx, self.skew], [self.skew_yx, self.fy]])

    # ------------------------------------------------------------------ the pipeline pieces
    def distort(self, u: np.ndarray) -> np.ndarray:
        """Normalized undistorted (..., 2) -> normalized distorted (..., 2)."""
        return distort(self.model, self.distortion, u)

    def undistort(self, ud: np.ndarray, *, tol: float = 1e-14, max_iter: int = 50) -> tuple[np.ndarray, np.ndarray]:
        """Normalized distorted (..., 2) -> (undistorted (..., 2) with NaN on failure, converged (...))."""
        return undistort(self.model, self.distortion, ud, tol=tol, max_iter=max_iter)

    def distortion_jacobian(self, u: np.ndarray) -> np.ndarray:
        """d(u_d)/d(u) at normalized undistorted coordinates u (..., 2) -> (..., 2, 2)."""
        return distortion_jacobian(self.model, self.distortion, u)

    def normalized_to_pixel(self, ud: np.ndarray) -> np.ndarray:
        """Eq. 4: distorted normalized (..., 2) -> pixel (s, l) (..., 2)."""
        ud = np.asarray(ud, dtype=np.float64)
        x, y = ud[..., 0], ud[..., 1]
        return np.stack([self.fx * x + self.skew * y + self.cx, self.skew_yx * x + self.fy * y + self.cy], axis=-1)

    def pixel_to_normalized(self, sl: np.ndarray) -> np.ndarray:
        """Exact inverse of eq. 4: pixel (s, l) (..., 2) -> distorted normalized (..., 2)."""
        sl = np.asarray(sl, dtype=np.float64)
        ds, dl = sl[..., 0] - self.cx, sl[..., 1] - self.cy
        det = self.fx * self.fy - self.skew * self.skew_yx
        return np.stack([(self.fy * ds - self.skew * dl) / det, (self.fx * dl - self.skew_yx * ds) / det], axis=-1)

    # ------------------------------------------------------------------ projection and its inverse
    def project(self, points_cam: np.ndarray) -> np.ndarray:
        """Project camera-frame points to pixels.

        Parameters
        ----------
        points_cam : array_like, shape (..., 3)
            Points (or directions) in the camera frame; a single (3,) point gives a (2,) result.

        Returns
        -------
        ndarray, shape (..., 2), float64
            (s, l) pixel coordinates; NaN rows for z <= 0 (behind or on the camera plane), non-finite
            input, and points beyond the distortion's fold (``|(x/z, y/z)| >= max_radius``).
        """
        p = np.asarray(points_cam, dtype=np.float64)
        if p.shape[-1:] != (3,):
            raise ValueError(f"points_cam must have shape (..., 3), got {p.shape}")
        z = p[..., 2]
        front = z > 0.0
        zs = np.where(front, z, 1.0)
        u = p[..., :2] / zs[..., None]
        sl = self.normalized_to_pixel(self.distort(u))
        sl[~self._valid(front, u)] = np.nan
        return sl

    def _valid(self, front: np.ndarray, u: np.ndarray) -> np.ndarray:
        if math.isinf(self.max_radius):
            return front
        with np.errstate(invalid="ignore"):
            return front & (np.hypot(u[..., 0], u[..., 1]) < self.max_radius)

    def unproject(self, sl: np.ndarray, *, return_converged: bool = False,
                  tol: float = 1e-14, max_iter: int = 50):
        """Pixels to unit rays in the camera frame (exact inverse of :meth:`project`).

        Parameters
        ----------
        sl : array_like, shape (..., 2)
            Pixel coordinates (s, l).
        return_converged : bool
            Also return the boolean mask of points whose undistortion converged.
        tol, max_iter
            Newton tolerance (normalized coordinates) and iteration bound, see :meth:`undistort`.

        Returns
        -------
        rays : ndarray, shape (..., 3)
            Unit vectors with z > 0; NaN rows where the undistortion did not converge (no preimage on
            the one-to-one branch ``|u| < max_radius``, or the Newton iteration failed).
        converged : ndarray of bool, shape (...)
            Only when `return_converged` is True.
        """
        sl = np.asarray(sl, dtype=np.float64)
        if sl.shape[-1:] != (2,):
            raise ValueError(f"sl must have shape (..., 2), got {sl.shape}")
        u, ok = self.undistort(self.pixel_to_normalized(sl), tol=tol, max_iter=max_iter)
        if not math.isinf(self.max_radius):
            ok = ok & (np.hypot(u[..., 0], u[..., 1]) < self.max_radius)
            u[~ok] = np.nan
        rays = np.concatenate([u, np.ones(u.shape[:-1] + (1,))], axis=-1)
        rays /= np.linalg.norm(rays, axis=-1, keepdims=True)
        return (rays, ok) if return_converged else rays

    def project_jacobian(self, points_cam: np.ndarray) -> np.ndarray:
        """Analytic d(s, l)/d(point) = K2 · D_dist(u) · du/dp.

        Parameters
        ----------
        points_cam : array_like, shape (..., 3)

        Returns
        -------
        ndarray, shape (..., 2, 3)
            NaN where :meth:`project` is NaN.
        """
        p = np.asarray(points_cam, dtype=np.float64)
        if p.shape[-1:] != (3,):
            raise ValueError(f"points_cam must have shape (..., 3), got {p.shape}")
        x, y, z = p[..., 0], p[..., 1], p[..., 2]
        front = z > 0.0
        iz = 1.0 / np.where(front, z, 1.0)
        u = np.stack([x * iz, y * iz], axis=-1)
        du_dp = np.zeros(p.shape[:-1] + (2, 3))
        du_dp[..., 0, 0] = iz
        du_dp[..., 1, 1] = iz
        du_dp[..., 0, 2] = -x * iz * iz
        du_dp[..., 1, 2] = -y * iz * iz
        J = self._K2 @ self.distortion_jacobian(u) @ du_dp
        J[~self._valid(front, u)] = np.nan
        return J

    # ------------------------------------------------------------------ image helpers
    def in_image(self, sl: np.ndarray) -> np.ndarray:
        """Mask of pixel coordinates inside the image: ``-0.5 <= s < W-0.5`` and ``-0.5 <= l < H-0.5``
        (half-open, so every point belongs to exactly one pixel ``round(s), round(l)``); NaN is False."""
        sl = np.asarray(sl, dtype=np.float64)
        s, l = sl[..., 0], sl[..., 1]
        with np.errstate(invalid="ignore"):
            return (s >= -0.5) & (s < self.width - 0.5) & (l >= -0.5) & (l < self.height - 0.5)

    def pixel_grid(self) -> np.ndarray:
        """Pixel centres as an (H, W, 2) float64 array: ``grid[l, s] = (s, l)``."""
        s, l = np.meshgrid(np.arange(self.width, dtype=np.float64), np.arange(self.height, dtype=np.float64))
        return np.stack([s, l], axis=-1)
