"""True coastline pixels: full-resolution GSHHG projected with the true camera.

Every GSHHG coastline piece inside the frame's footprint is densified (linear in lon/lat between GSHHG
vertices, which are ≲ 1 km apart) so consecutive points are ≤ ``step_px`` apart in the image, projected
through the true pose and camera model, and kept where it falls inside the image on the Earth's visible side.
"""

from __future__ import annotations

import numpy as np

from renderlab.worlds.earth import wgs84


def project_ecef(camera, pos_ecef, R_ecef_from_cam, p_ecef) -> np.ndarray:
    """Pixel (s, l) (K, 2) of ECEF points (NaN behind the camera)."""
    p_cam = (np.asarray(p_ecef, float) - pos_ecef) @ R_ecef_from_cam
    return camera.project(p_cam)


def coastline_pixels(camera, pos_ecef, R_ecef_from_cam, lines_lonlat: list[np.ndarray], step_px: float = 0.25):
    """(s, l, lon_deg, lat_deg, piece) arrays of densified, visible, in-image coastline points."""
    out = []
    for k, xy in enumerate(lines_lonlat):
        if len(xy) < 2:
            continue
        p = wgs84.geodetic_to_ecef(np.radians(xy[:, 1]), np.radians(xy[:, 0]))
        sl = project_ecef(camera, pos_ecef, R_ecef_from_cam, p)
        seg = np.linalg.norm(np.diff(sl, axis=0), axis=1)
        seg = np.where(np.isfinite(seg), seg, 0.0)
        n = np.maximum(1, np.ceil(seg / step_px).astype(int))
        i0 = np.repeat(np.arange(len(n)), n)
        f = (np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)) / np.repeat(n, n)
        ll = np.concatenate([xy[i0] + f[:, None] * (xy[i0 + 1] - xy[i0]), xy[-1:]])
        out.append((ll, np.full(len(ll), k)))
    if not out:
        z = np.zeros(0)
        return z, z, z, z, np.zeros(0, int)
    ll = np.concatenate([o[0] for o in out])
    piece = np.concatenate([o[1] for o in out])
    lat, lon = np.radians(ll[:, 1]), np.radians(ll[:, 0])
    p = wgs84.geodetic_to_ecef(lat, lon)
    sl = project_ecef(camera, pos_ecef, R_ecef_from_cam, p)
    up = wgs84.R_ecef_from_enu(lat, lon)[..., 2]
    facing = np.sum(up * (pos_ecef - p), -1) > 0
    keep = facing & np.all(np.isfinite(sl), 1) & camera.in_image(np.nan_to_num(sl, nan=-1e9))
    return sl[keep, 0], sl[keep, 1], ll[keep, 0], ll[keep, 1], piece[keep]
