r"""Landmark prediction: the synthetic image of a maplet seen with the a-priori pose (the projection, eqs. 1–4,
and the search distance are the shared :mod:`estimators.landmarks.pose`).

Synthetic image (Retina "Synthetic Image Generation"): the pixels covering the maplet (bounding box of
its projected grid points) are taken through the inverse camera model at k×k sub-pixel positions, the
lines of sight are intersected with the maplet facets, a shadow ray is cast from every hit toward the
sun, and each unshadowed hit is lit with McEwen's law (eqs. 5–8) and the maplet albedo. The k² samples
are averaged (supersampling; one fused numba kernel, :func:`~.raytrace.shade_pixels`, or
:func:`~.raytrace.shade_pinhole`, which also makes the rays, for a distortion-free camera) and an optional
Gaussian PSF matching the camera is applied
(normalised over the valid pixels). A pixel is valid when all its samples hit the maplet.
For a distortion-free camera the default ``tracer="raster"`` computes the same image by z-buffer
rasterisation of the facets and a per-frame shadow sweep over the maplet grid
(:func:`~.raster.raster_pinhole`; the ray caster stays the reference, ``tracer="numba"``).
The McEwen weight β is exp(−α/α0) (eq. 5) or a tabulated L(α) fitted to the body's law
(``L_table``, :func:`estimators.onboard_photometry.fit_lunar_lambert_L`).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from estimators.landmarks.pose import CameraPoseEstimate, project_point
from estimators.onboard_photometry import DEFAULT_ALPHA0, mcewen_relative
from estimators.retina.maplet_mesh import MapletMesh
from estimators.retina.raster import pinhole_box, raster_pinhole
from estimators.retina.raytrace import shade_pinhole, shade_pixels
from estimators.retina.raytrace_numpy import trace_rays_numpy
from renderlab.geometry.camera import CameraModel


@dataclass(frozen=True)
class TemplateOptions:
    """Options of the synthetic image.

    Attributes
    ----------
    supersample : int
        k: k×k rays per pixel.
    psf_sigma_px : float
        Gaussian PSF standard deviation, px (0: none).
    alpha0, ls_weight : float
        McEwen parameters (eq. 5).
    shadow_rays : bool
        Cast shadow rays (False: only attached shadows, cos i ≤ 0).
    max_size_px : int
        Refuse templates larger than this on either side (the landmark is too close).
    tracer : {"raster", "numba", "numpy"}
        ``raster``: z-buffer rasterisation + shadow sweep (:mod:`.raster`; pinhole cameras, others
        use ``numba``); ``numba``: grid-DDA ray casting, every shadow ray cast (the reference); ``numpy``:
        the plain-numpy brute force (benchmark baseline, slow).
    L_table : tuple of float
        L(α) tabulated over [0, π] replacing β = exp(−α/α0) (empty: eq. 5's exponential).
    shadow_grid_step : float
        Spacing of the sun-aligned shadow sweep grid, maplet cells (``raster`` only).
    """

    supersample: int = 3
    psf_sigma_px: float = 0.0
    alpha0: float = DEFAULT_ALPHA0
    ls_weight: float = 2.0
    shadow_rays: bool = True
    max_size_px: int = 256
    tracer: str = "raster"
    L_table: tuple = ()
    shadow_grid_step: float = 0.5


@dataclass
class Template:
    """A predicted landmark image. ``image[y, x]`` is pixel (s0 + x, l0 + y) of the camera image;
    ``shadow_fraction`` is the fraction of maplet-hitting samples facing the sun but in cast shadow."""

    image: np.ndarray
    valid: np.ndarray
    s0: int
    l0: int
    shadow_fraction: float


@functools.lru_cache(maxsize=64)
def _pixel_maps_cached(key: tuple) -> tuple[np.ndarray, np.ndarray]:
    K = np.array(key, dtype=np.float64).reshape(3, 3)
    Kinv = np.linalg.inv(K)
    K.flags.writeable = Kinv.flags.writeable = False
    return K, Kinv


def _pixel_maps(camera: CameraModel) -> tuple[np.ndarray, np.ndarray]:
    """The pinhole pixel map K (eqs. 3–4) and its inverse, computed once per camera (read-only)."""
    return _pixel_maps_cached(tuple(np.asarray(camera.K_matrix, dtype=np.float64).ravel().tolist()))


@functools.lru_cache(maxsize=16)
def _table(L_table: tuple) -> np.ndarray:
    """``TemplateOptions.L_table`` as the kernels' float64 array, converted once per table (read-only)."""
    a = np.asarray(L_table, dtype=np.float64).reshape(-1)
    a.flags.writeable = False
    return a


def template_box(mesh: MapletMesh, camera: CameraModel, pose: CameraPoseEstimate) -> tuple[int, int, int, int] | None:
    """Integer pixel box (s_min, l_min, s_max, l_max) covering the projected maplet grid, or None."""
    pts = mesh.points_body.reshape(-1, 3)
    if camera.model == "pinhole":  # eqs. 1–4 without distortion, one numba loop
        s0, l0, s1, l1, ok = pinhole_box(pts, np.asarray(pose.position_m, float), np.asarray(pose.R_body_from_cam, float),
                                         np.ascontiguousarray(camera.K_matrix, dtype=np.float64))
        return (int(s0), int(l0), int(s1), int(l1)) if ok else None
    else:
        sl = project_point(camera, pose, pts)
    if not np.all(np.isfinite(sl)):
        return None
    lo = np.floor(sl.min(axis=0)).astype(int)
    hi = np.ceil(sl.max(axis=0)).astype(int)
    return int(lo[0]), int(lo[1]), int(hi[0]), int(hi[1])


def render_template(mesh: MapletMesh, camera: CameraModel, pose: CameraPoseEstimate, sun_body: np.ndarray,
                    options: TemplateOptions = TemplateOptions()) -> Template | None:
    """Ray-trace the predicted image of a maplet (module docstring); None if it cannot be made."""
    box = template_box(mesh, camera, pose)
    if box is None:
        return None
    s_min, l_min, s_max, l_max = box
    w, h = s_max - s_min + 1, l_max - l_min + 1
    if w > options.max_size_px or h > options.max_size_px or w < 2 or h < 2:
        return None
    k = int(options.supersample)
    M = mesh.maplet
    R_mb = np.asarray(M.R_body_from_maplet, float).T
    R_bc = np.asarray(pose.R_body_from_cam, float)
    o_m = R_mb @ (np.asarray(pose.position_m, float) - np.asarray(M.center_m, float))
    sun_m = R_mb @ (np.asarray(sun_body, float) / np.linalg.norm(sun_body))
    eps = 1e-6 * mesh.spacing + 1e-9
    L_table = _table(tuple(options.L_table))
    kernel_args = (mesh.heights, mesh.cell_min, mesh.cell_max, mesh.block_min, mesh.block_max, mesh.spacing,
                   mesh.normals, mesh.albedo, sun_m, bool(options.shadow_rays), float(options.alpha0), L_table,
                   float(options.ls_weight), eps)
    done = False
    if options.tracer == "raster" and camera.model == "pinhole":
        K, Kinv = _pixel_maps(camera)
        val, nhit, nsh, _, done = raster_pinhole(o_m, np.ascontiguousarray(R_mb @ R_bc), K, Kinv,
                                                 s_min, l_min, w, h, k, *kernel_args,
                                                 float(options.shadow_grid_step))
    if done:
        pass
    elif options.tracer != "numpy" and camera.model == "pinhole":  # rays made inside the kernel
        val, nhit, nsh = shade_pinhole(o_m, np.ascontiguousarray(R_mb @ R_bc), _pixel_maps(camera)[1],
                                       s_min, l_min, w, h, k, *kernel_args)
    else:
        off = (np.arange(k) + 0.5) / k - 0.5
        ox, oy = np.meshgrid(off, off)
        ls, ss = np.meshgrid(np.arange(l_min, l_max + 1, dtype=float), np.arange(s_min, s_max + 1, dtype=float),
                             indexing="ij")
        sl = np.stack([ss[..., None] + ox.ravel(), ls[..., None] + oy.ravel()], axis=-1).reshape(-1, 2)
        d_m = camera.unproject(sl) @ (R_mb @ R_bc).T
        ok_ray = np.all(np.isfinite(d_m), axis=1)
        if options.tracer == "numpy":
            img, cover, shadow_fraction = _shade_numpy(mesh, o_m, d_m, ok_ray, sun_m, options, eps, k * k)
        else:
            d_m[~ok_ray] = np.nan
            val, nhit, nsh = shade_pixels(o_m, np.ascontiguousarray(d_m), k * k, *kernel_args)
    if options.tracer != "numpy":
        img, cover = val, nhit / (k * k)
        shadow_fraction = float(nsh.sum() / max(nhit.sum(), 1))
    img, cover = img.reshape(h, w), cover.reshape(h, w)
    valid = cover >= 1.0 - 1e-12
    if options.psf_sigma_px > 0:
        from scipy.ndimage import gaussian_filter

        num = gaussian_filter(img * valid, options.psf_sigma_px, mode="constant")
        den = gaussian_filter(valid.astype(float), options.psf_sigma_px, mode="constant")
        img = np.where(valid, num / np.maximum(den, 1e-12), 0.0)
    return Template(image=np.where(valid, img, 0.0), valid=valid, s0=s_min, l0=l_min,
                    shadow_fraction=shadow_fraction)


def _shade_numpy(mesh, o_m, d_m, ok_ray, sun_m, options, eps, k2):
    """Plain-numpy synthetic image (brute-force tracer, vectorised shading): the benchmark baseline and an
    independent check of the fused numba kernel."""
    M = mesh.maplet
    d = np.where(ok_ray[:, None], d_m, np.array([0.0, 0.0, 1.0]))
    hit, P, Nn, shadow = trace_rays_numpy(mesh, np.broadcast_to(o_m, d.shape).copy(), d,
                                          sun_m if options.shadow_rays else np.zeros(3), eps)
    hit &= ok_ray
    value = np.zeros(len(d))
    if hit.any():
        to_cam = o_m[None, :] - P[hit]
        to_cam /= np.linalg.norm(to_cam, axis=1, keepdims=True)
        n_h = Nn[hit]
        cos_i = n_h @ sun_m
        cos_r = np.einsum("ij,ij->i", n_h, to_cam)
        phase = np.arccos(np.clip(to_cam @ sun_m, -1.0, 1.0))
        alb = _bilinear(M.albedo, P[hit, 0] / M.spacing_m + (M.n - 1) / 2, P[hit, 1] / M.spacing_m + (M.n - 1) / 2)
        v = mcewen_relative(cos_i, cos_r, phase, alb, options.alpha0, options.ls_weight, options.L_table or None)
        v[shadow[hit] & (cos_i > 0)] = 0.0
        value[hit] = v
    lit_shadow = (shadow & hit) & (np.einsum("ij,j->i", np.nan_to_num(Nn), sun_m) > 0)
    return (value.reshape(-1, k2).mean(axis=1), hit.reshape(-1, k2).mean(axis=1),
            float(lit_shadow.sum() / max(hit.sum(), 1)))


def _bilinear(grid: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Bilinear sample of ``grid[row v, col u]`` (clamped at the border)."""
    n1, n0 = grid.shape[0] - 1, grid.shape[1] - 1
    u = np.clip(u, 0, n0)
    v = np.clip(v, 0, n1)
    i0 = np.clip(np.floor(u).astype(int), 0, n0 - 1)
    j0 = np.clip(np.floor(v).astype(int), 0, n1 - 1)
    fu, fv = u - i0, v - j0
    g = np.asarray(grid, float)
    return ((1 - fu) * (1 - fv) * g[j0, i0] + fu * (1 - fv) * g[j0, i0 + 1]
            + (1 - fu) * fv * g[j0 + 1, i0] + fu * fv * g[j0 + 1, i0 + 1])
