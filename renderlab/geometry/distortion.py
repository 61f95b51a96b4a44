r"""Lens distortion models on normalized (gnomonic) image coordinates.

All models act on the normalized coordinates :math:`\mathbf{u} = (x, y) = (x_C/z_C, y_C/z_C)`
of a camera-frame point, i.e. focal-plane coordinates in units of the focal length, and return
distorted normalized coordinates :math:`\mathbf{u}_d`. This is the "distortion model" step between
the gnomonic projection (Retina paper, eq. 3) and the pixel map (eq. 4). With :math:`r^2 = x^2+y^2`:

``pinhole``
    :math:`\mathbf{u}_d = \mathbf{u}`.
``brown`` (Brown-Conrady exactly as OpenCV's ``projectPoints``; keys ``k1 k2 k3 p1 p2``)
    :math:`x_d = x(1+k_1r^2+k_2r^4+k_3r^6) + 2p_1xy + p_2(r^2+2x^2)`,
    :math:`y_d = y(1+k_1r^2+k_2r^4+k_3r^6) + p_1(r^2+2y^2) + 2p_2xy`.
``owen`` (W. M. Owen 2011, "Methods of Optical Navigation"; the form of NASA GIANT's ``OwenModel``;
keys ``e1 .. e6``)
    :math:`\Delta = (e_2r^2 + e_4r^4 + e_5y + e_6x)[x, y]^T + (e_1r + e_3r^3)[-y, x]^T`,
    :math:`\mathbf{u}_d = \mathbf{u} + \Delta`. ``e2, e4`` radial, ``e5, e6`` tip/tilt/prism,
    ``e1, e3`` pinwheel.
``opencv`` (OpenCV's 14-coefficient rational + thin-prism + tilt model): :mod:`.distortion_opencv`.
``kannala_brandt`` (the fisheye model of ``cv2.fisheye``, keys ``k1 .. k4``): :mod:`.fisheye`.

Owen coefficients are for focal-plane coordinates in units of the focal length; coefficients fitted in
millimetres (GIANT, SPC: :math:`x_I = f\,x`) convert as :math:`e_n = e_n^{mm} f^n` for the :math:`r^n`
terms (n = 1..4) and :math:`e_{5,6} = e_{5,6}^{mm} f` (:func:`owen_coefficients_from_mm`).

The inverse (undistortion) has no closed form; :func:`undistort` solves :math:`D(\mathbf{u}) =
\mathbf{u}_d` by Newton's method with the analytic Jacobian of :func:`distortion_jacobian`.
"""

from __future__ import annotations

import math
from collections import namedtuple
from collections.abc import Mapping

import numpy as np

from renderlab.errors import UserError
from renderlab.inputs import COEFF_MAX, short

from . import distortion_opencv, fisheye

__all__ = ["DISTORTION_KEYS", "MODELS", "normalize_distortion", "distort", "distortion_jacobian", "undistort",
           "max_valid_radius", "owen_coefficients_from_mm"]

_MODULES = {"opencv": distortion_opencv, "kannala_brandt": fisheye}  # models whose kernels live in their own module
#: Allowed models and their coefficient names (in manifest order).
DISTORTION_KEYS: dict[str, tuple[str, ...]] = {
    "pinhole": (),
    "brown": ("k1", "k2", "k3", "p1", "p2"),
    "owen": ("e1", "e2", "e3", "e4", "e5", "e6"), **{name: mod.KEYS for name, mod in _MODULES.items()},
}
MODELS: tuple[str, ...] = tuple(DISTORTION_KEYS)


def _is_real(value) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))


def normalize_distortion(model: str, distortion: Mapping[str, float] | None, where: str = "camera") -> dict[str, float]:
    """Validate distortion coefficients and return the full, ordered coefficient dict of `model`.

    Parameters
    ----------
    model : str
        Distortion model name, one of :data:`MODELS`.
    distortion : mapping or None
        Coefficients by name; missing keys are zero. A ``pinhole`` model accepts other models' keys
        only when they are all zero (a manifest may spell out zeros), and returns ``{}``.
    where : str
        Prefix used in error messages (``"camera"`` gives ``camera.distortion.k1 ...``).

    Returns
    -------
    dict
        ``{key: float}`` with every key of the model, in the model's order.

    Raises
    ------
    UserError
        Unknown model, non-mapping distortion, unknown key, or a non-finite / non-numeric value.
    """
    if model not in DISTORTION_KEYS:
        raise UserError(f"{where}.model must be one of {', '.join(repr(m) for m in MODELS)}, got {short(model)}")
    if distortion is None:
        distortion = {}
    if not isinstance(distortion, Mapping):
        raise UserError(f"{where}.distortion must be a table of coefficients, got {type(distortion).__name__}")
    keys = DISTORTION_KEYS[model]
    out = {k: 0.0 for k in keys}
    for key, value in distortion.items():
        name = f"{where}.distortion.{short(str(key), 24).strip(chr(39))}"
        if not _is_real(value) or not np.isfinite(float(value)) or abs(float(value)) > COEFF_MAX:
            raise UserError(f"{name} must be a finite number of at most {COEFF_MAX:g} in size, got {short(value)}")
        if key in keys:
            out[key] = float(value)
        elif model == "pinhole" and any(key in ks for ks in DISTORTION_KEYS.values()):
            if float(value) != 0.0:
                raise UserError(f"{name} is {float(value)!r} but {where}.model is 'pinhole' (no distortion)")
        else:
            raise UserError(f"{name}: unknown coefficient for model '{model}' (allowed: {', '.join(keys) or 'none'})")
    return out


def owen_coefficients_from_mm(e_mm: Mapping[str, float], focal_length_mm: float) -> dict[str, float]:
    """Convert Owen coefficients fitted on millimetre focal-plane coordinates to normalized ones.

    With :math:`x_{mm} = f\\,x`, the distortion in normalized units is :math:`\\Delta_{mm}/f`, so the
    coefficient of an :math:`r^n` term scales as :math:`f^n` (``e1``: f, ``e2``: f², ``e3``: f³,
    ``e4``: f⁴) and the tip/tilt terms ``e5``, ``e6`` scale as f.

    Parameters
    ----------
    e_mm : mapping
        Owen coefficients ``e1..e6`` (missing = 0) for coordinates in mm.
    focal_length_mm : float
        Focal length in mm.

    Returns
    -------
    dict
        Coefficients ``e1..e6`` for coordinates in units of the focal length.
    """
    coeffs = normalize_distortion("owen", e_mm, where="owen")
    f = float(focal_length_mm)
    if not (np.isfinite(f) and f > 0):
        raise UserError(f"focal_length_mm must be a positive finite number, got {short(focal_length_mm)}")
    power = {"e1": 1, "e2": 2, "e3": 3, "e4": 4, "e5": 1, "e6": 1}
    return {k: v * f ** power[k] for k, v in coeffs.items()}


# ----------------------------------------------------------------------------- component kernels
def _distort_xy(model: str, c: Mapping[str, float], x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    if model == "pinhole":
        return x.copy(), y.copy()
    if model in _MODULES:
        return _MODULES[model].distort_xy(c, x, y)
    x2, y2, xy = x * x, y * y, x * y
    r2 = x2 + y2
    if model == "brown":
        k1, k2, k3, p1, p2 = c["k1"], c["k2"], c["k3"], c["p1"], c["p2"]
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        return (x * radial + 2.0 * p1 * xy + p2 * (r2 + 2.0 * x2),
                y * radial + p1 * (r2 + 2.0 * y2) + 2.0 * p2 * xy)
    if model == "owen":
        r = np.sqrt(r2)
        a = r2 * (c["e2"] + c["e4"] * r2) + c["e5"] * y + c["e6"] * x  # radial + tip/tilt
        b = r * (c["e1"] + c["e3"] * r2)                                # pinwheel
        return x + a * x - b * y, y + a * y + b * x
    raise ValueError(f"unknown distortion model {model!r}")


def _jacobian_xy(model: str, c: Mapping[str, float], x: np.ndarray, y: np.ndarray):
    """(J00, J01, J10, J11) of d(x_d, y_d)/d(x, y)."""
    if model == "pinhole":
        one, zero = np.ones_like(x), np.zeros_like(x)
        return one, zero, zero, one.copy()
    if model in _MODULES:
        return _MODULES[model].jacobian_xy(c, x, y)
    x2, y2, xy = x * x, y * y, x * y
    r2 = x2 + y2
    if model == "brown":
        k1, k2, k3, p1, p2 = c["k1"], c["k2"], c["k3"], c["p1"], c["p2"]
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        dradial = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2)  # d radial / d r²
        off = 2.0 * xy * dradial + 2.0 * p1 * x + 2.0 * p2 * y
        return (radial + 2.0 * x2 * dradial + 2.0 * p1 * y + 6.0 * p2 * x, off,
                off, radial + 2.0 * y2 * dradial + 6.0 * p1 * y + 2.0 * p2 * x)
    if model == "owen":
        e1, e2, e3, e4, e5, e6 = c["e1"], c["e2"], c["e3"], c["e4"], c["e5"], c["e6"]
        r = np.sqrt(r2)
        a = r2 * (e2 + e4 * r2) + e5 * y + e6 * x
        b = r * (e1 + e3 * r2)
        da_dr2 = e2 + 2.0 * e4 * r2
        da_dx = 2.0 * x * da_dr2 + e6
        da_dy = 2.0 * y * da_dr2 + e5
        # db/dx = (e1 + 3 e3 r²) x/r: x/r is bounded and multiplied by x or y, so 0 is its limit at r = 0
        pos = r > 0.0
        inv_r = np.where(pos, 1.0 / np.where(pos, r, 1.0), 0.0)
        db_dr = e1 + 3.0 * e3 * r2
        db_dx = db_dr * x * inv_r
        db_dy = db_dr * y * inv_r
        return (1.0 + a + x * da_dx - y * db_dx, x * da_dy - b - y * db_dy,
                y * da_dx + b + x * db_dx, 1.0 + a + y * da_dy + x * db_dy)
    raise ValueError(f"unknown distortion model {model!r}")


# ----------------------------------------------------------------------------- public API
def max_valid_radius(model: str, coeffs: Mapping[str, float], *, r_max: float = 100.0,
                     n_radii: int = 600, n_angles: int = 72, margin: float = 0.995) -> float:
    """Undistorted radius r = |u| below which the distortion is locally invertible (det J > 0).

    Polynomial distortions fold over far from the axis (e.g. Brown with k1 < 0: r(1 + k1 r²) peaks at
    r = 1/sqrt(-3 k1)); beyond the fold, projections are meaningless and can land back inside the image.
    This scans ``det J`` on `n_angles` rays over a geometric grid of `n_radii` radii in [1e-3, `r_max`],
    refines each ray's first sign change by bisection, and returns `margin` times the smallest fold
    radius, or ``inf`` when no ray folds (pinhole, mild distortion).
    """
    if model == "pinhole":
        return math.inf
    r = np.geomspace(1e-3, r_max, n_radii)
    th = np.linspace(0.0, 2.0 * np.pi, n_angles, endpoint=False)
    c, s = np.cos(th), np.sin(th)
    bad = lambda rr, cc, ss: ~_unfolded(model, coeffs, cc * rr, ss * rr)  # noqa: E731
    b = bad(r[None, :], c[:, None], s[:, None])
    folded = b.any(axis=1)
    if not folded.any():
        return math.inf
    first = np.argmax(b[folded], axis=1)
    hi = r[first]
    lo = np.where(first > 0, r[np.maximum(first - 1, 0)], 0.0)
    cf, sf = c[folded], s[folded]
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        m = bad(mid, cf, sf)
        hi = np.where(m, mid, hi)
        lo = np.where(m, lo, mid)
    return float(margin * np.min(lo))


def distort(model: str, coeffs: Mapping[str, float], u: np.ndarray) -> np.ndarray:
    """Apply the distortion model to normalized coordinates.

    Parameters
    ----------
    model : str
        One of :data:`MODELS`.
    coeffs : mapping
        Full coefficient dict (as returned by :func:`normalize_distortion`).
    u : array_like, shape (..., 2)
        Undistorted normalized coordinates (x/z, y/z).

    Returns
    -------
    ndarray, shape (..., 2)
        Distorted normalized coordinates.
    """
    u = np.asarray(u, dtype=np.float64)
    xd, yd = _distort_xy(model, coeffs, u[..., 0], u[..., 1])
    return np.stack([xd, yd], axis=-1)


def distortion_jacobian(model: str, coeffs: Mapping[str, float], u: np.ndarray) -> np.ndarray:
    """Analytic Jacobian d(u_d)/d(u) of :func:`distort`.

    Parameters
    ----------
    model, coeffs
        As for :func:`distort`.
    u : array_like, shape (..., 2)
        Undistorted normalized coordinates.

    Returns
    -------
    ndarray, shape (..., 2, 2)
        ``J[..., i, j] = d u_d[i] / d u[j]``. For the Owen pinwheel term ``e1 r [-y, x]``, which is
        O(r²) but not twice differentiable at r = 0, the derivative at the origin is its limit (zero).
    """
    u = np.asarray(u, dtype=np.float64)
    j00, j01, j10, j11 = _jacobian_xy(model, coeffs, u[..., 0], u[..., 1])
    return np.stack([np.stack([j00, j01], axis=-1), np.stack([j10, j11], axis=-1)], axis=-2)


def _first_guess(model: str, c: Mapping[str, float], ax: np.ndarray, ay: np.ndarray):
    """Newton start for the finite targets (ax, ay) (n,): ``u0 = ud - (D(ud) - ud)``, or ``ud`` where that is worse.

    Returns the start point (bx, by), its residual ``D(b) - a`` (rx, ry) and the residual's max-norm ``err``.
    """
    dx, dy = _distort_xy(model, c, ax, ay)
    bx, by = 2.0 * ax - dx, 2.0 * ay - dy
    err0 = np.maximum(np.abs(dx - ax), np.abs(dy - ay))
    dx, dy = _distort_xy(model, c, bx, by)
    rx, ry = dx - ax, dy - ay
    err = np.maximum(np.abs(rx), np.abs(ry))
    worse = ~(err <= err0)
    if worse.any():
        bx[worse], by[worse] = ax[worse], ay[worse]
        dx, dy = _distort_xy(model, c, bx[worse], by[worse])
        rx[worse], ry[worse] = dx - ax[worse], dy - ay[worse]
        err[worse] = np.maximum(np.abs(rx[worse]), np.abs(ry[worse]))
    return bx, by, rx, ry, err


def _damped_step(model: str, c: Mapping[str, float], ax, ay, bx, by, err, sx, sy):
    """Trial points ``b - t s`` of the Newton step (sx, sy) from (bx, by) with residual norm ``err`` toward (ax, ay):
    t = 1, halved (up to 30 times) where that does not reduce the residual (all arrays shape (n,)).

    Returns the trial points (nx, ny), their residual (nrx, nry) and its max-norm ``nerr`` (the full step's where
    no halving helped).
    """
    nx, ny = bx - sx, by - sy
    dx, dy = _distort_xy(model, c, nx, ny)
    nrx, nry = dx - ax, dy - ay
    nerr = np.maximum(np.abs(nrx), np.abs(nry))
    back = np.flatnonzero(~(nerr < err) & np.isfinite(sx) & np.isfinite(sy))
    t = 1.0
    for _k in range(30):  # backtracking on the (rare) points whose full step did not help
        if back.size == 0:
            break
        t *= 0.5
        px, py = bx[back] - t * sx[back], by[back] - t * sy[back]
        qx, qy = _distort_xy(model, c, px, py)
        qrx, qry = qx - ax[back], qy - ay[back]
        qerr = np.maximum(np.abs(qrx), np.abs(qry))
        ok = qerr < err[back]
        sel = back[ok]
        nx[sel], ny[sel], nrx[sel], nry[sel], nerr[sel] = px[ok], py[ok], qrx[ok], qry[ok], qerr[ok]
        back = back[~ok]
    return nx, ny, nrx, nry, nerr


#: points still iterating in :func:`undistort` (each (n,)): output index, target, threshold, point, residual, its norm
_Active = namedtuple("_Active", "idx ax ay th bx by rx ry err")


def _newton_iteration(model: str, c: Mapping[str, float], a: _Active) -> tuple[_Active, np.ndarray]:
    """One damped Newton iteration (closed-form 2x2 solve, analytic J) of the active points.

    Returns the new state (points moved only where the residual decreased) and that mask, shape (n,).
    """
    j00, j01, j10, j11 = _jacobian_xy(model, c, a.bx, a.by)
    det = j00 * j11 - j01 * j10
    sx = (j11 * a.rx - j01 * a.ry) / det
    sy = (j00 * a.ry - j10 * a.rx) / det
    nx, ny, nrx, nry, nerr = _damped_step(model, c, a.ax, a.ay, a.bx, a.by, a.err, sx, sy)
    improved = nerr < a.err
    return (a._replace(bx=np.where(improved, nx, a.bx), by=np.where(improved, ny, a.by),
                       rx=np.where(improved, nrx, a.rx), ry=np.where(improved, nry, a.ry),
                       err=np.where(improved, nerr, a.err)), improved)


def _unfolded(model: str, c: Mapping[str, float], x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """``det J > 0`` at (x, y): on the invertible, unfolded branch of the distortion (NaN/inf: folded)."""
    j00, j01, j10, j11 = _jacobian_xy(model, c, x, y)
    return j00 * j11 - j01 * j10 > 0.0


def undistort(model: str, coeffs: Mapping[str, float], ud: np.ndarray, *, tol: float = 1e-14,
              max_iter: int = 50) -> tuple[np.ndarray, np.ndarray]:
    """Invert the distortion: find u with ``distort(u) == ud`` by damped Newton iteration.

    Each point starts at ``u = 2 ud - D(ud)`` (or ``ud`` if that is worse) and iterates
    ``u <- u - t J(u)^-1 (D(u) - ud)`` (closed-form 2x2 solve, analytic J) with ``t = 1``, halved (up to
    30 times) while the step does not reduce the residual.
    A point has converged when ``max|D(u) - ud| <= tol * max(1, |ud|)`` and ``det J(u) > 0`` there (the
    solution is on the invertible, unfolded branch of the distortion). A point whose residual can no
    longer be reduced, or that exhausts `max_iter`, has not converged.

    Parameters
    ----------
    model, coeffs
        As for :func:`distort`.
    ud : array_like, shape (..., 2)
        Distorted normalized coordinates.
    tol : float
        Residual tolerance in normalized coordinates (default 1e-14).
    max_iter : int
        Maximum Newton iterations per point.

    Returns
    -------
    u : ndarray, shape (..., 2)
        Undistorted normalized coordinates; NaN where not converged (or the input is not finite).
    converged : ndarray of bool, shape (...)
        True where the iteration met the tolerance.
    """
    ud = np.asarray(ud, dtype=np.float64)
    shape = ud.shape[:-1]
    tx = np.ascontiguousarray(ud[..., 0]).ravel()
    ty = np.ascontiguousarray(ud[..., 1]).ravel()
    finite = np.isfinite(tx) & np.isfinite(ty)
    if model == "pinhole":
        u = np.stack([np.where(finite, tx, np.nan), np.where(finite, ty, np.nan)], axis=-1)
        return u.reshape(shape + (2,)), finite.reshape(shape)

    thresh = tol * np.maximum(1.0, np.maximum(np.abs(tx), np.abs(ty)))
    out_x, out_y, out_e = np.full(tx.shape, np.nan), np.full(tx.shape, np.nan), np.full(tx.shape, np.inf)

    idx = np.flatnonzero(finite)
    ax, ay = tx[idx], ty[idx]  # targets
    a = _Active(idx, ax, ay, thresh[idx], *_first_guess(model, coeffs, ax, ay))
    stop = a.err <= a.th
    with np.errstate(all="ignore"):
        for _ in range(max_iter):
            if stop.any():  # retire finished points, compact the active set
                sel = a.idx[stop]
                out_x[sel], out_y[sel], out_e[sel] = a.bx[stop], a.by[stop], a.err[stop]
                a = _Active(*(v[~stop] for v in a))
            if a.idx.size == 0:
                break
            a, improved = _newton_iteration(model, coeffs, a)
            stop = (a.err <= a.th) | ~improved  # converged, or stuck (no further decrease possible)
    out_x[a.idx], out_y[a.idx], out_e[a.idx] = a.bx, a.by, a.err

    converged = finite & (out_e <= thresh)
    ci = np.flatnonzero(converged)
    if ci.size:
        converged[ci[~_unfolded(model, coeffs, out_x[ci], out_y[ci])]] = False
    out_x[~converged] = np.nan
    out_y[~converged] = np.nan
    return np.stack([out_x, out_y], axis=-1).reshape(shape + (2,)), converged.reshape(shape)
