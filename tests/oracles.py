"""Independent numpy ray-casting oracles for analytic scenes (no renderer code involved)."""

from __future__ import annotations

import numpy as np


def camera_rays(spec, sl):
    """World-frame ray origins and unit directions for pixel coordinates ``sl`` (N, 2), pinhole only,
    built from K directly (not from CameraModel.unproject)."""
    cam = spec.camera
    K = np.array([[cam.fx, cam.skew], [cam.skew_yx, cam.fy]])
    uv = np.linalg.solve(K, (sl - [cam.cx, cam.cy]).T).T
    d_cam = np.column_stack([uv, np.ones(len(uv))])
    d_cam /= np.linalg.norm(d_cam, axis=1, keepdims=True)
    R = spec.pose.rotation.as_matrix()
    o = np.broadcast_to(spec.pose.position_m, d_cam.shape)
    return o, d_cam @ R.T


def hit_sphere(o, d, c, r):
    """Distance along unit rays to the first hit of a sphere (inf if none)."""
    oc = o - c
    b = np.einsum("ij,ij->i", oc, d)
    with np.errstate(invalid="ignore"):
        disc = b**2 - (np.einsum("ij,ij->i", oc, oc) - r * r)
        t = -b - np.sqrt(np.where(disc >= 0, disc, np.nan))
    return np.where((disc >= 0) & (t > 0), t, np.inf)


def hit_plane_z0(o, d, half_size=None):
    """Distance to the plane z = 0 (optionally limited to |x|,|y| <= half_size)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -o[:, 2] / d[:, 2]
    ok = t > 0
    if half_size is not None:
        p = o + t[:, None] * d
        ok &= (np.abs(p[:, 0]) <= half_size[0]) & (np.abs(p[:, 1]) <= half_size[1])
    return np.where(ok, t, np.inf)


def hit_box(o, d, lo, hi):
    """Slab test for an axis-aligned box: distance to the entry point (inf if missed)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (lo - o) / d
        t2 = (hi - o) / d
    tmin = np.nanmax(np.minimum(t1, t2), axis=1)
    tmax = np.nanmin(np.maximum(t1, t2), axis=1)
    ok = (tmax >= np.maximum(tmin, 0))
    return np.where(ok, np.maximum(tmin, 0), np.inf)
