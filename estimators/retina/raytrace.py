r"""Ray–maplet intersection and shadow rays ("single-bounce" ray tracing, Retina synthetic image step 3–4).

Kernels (numba) walk the maplet's cell grid with a 2-D DDA (see :mod:`.maplet_mesh`) and test the two
triangles of each candidate cell with the Möller–Trumbore algorithm. Work is done in *grid units*
(u = column index, v = row index, z in metres): an affine change of coordinates keeps the ray parameter
t, so hit distances are metric. :func:`trace_bruteforce` is the plain-numpy reference (every ray against
every facet); the tests use it as the oracle and the benchmark as the speed baseline.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from estimators.onboard_photometry import mcewen_scalar

_EPS = 1e-12
_INF = 1e300


@njit(cache=True, inline="always")
def _tri(ou, ov, oz, du, dv, dz, au, av, az, bu, bv, bz, cu, cv, cz):
    """Möller–Trumbore: ray parameter of the hit with triangle ABC, or -1."""
    e1u, e1v, e1z = bu - au, bv - av, bz - az
    e2u, e2v, e2z = cu - au, cv - av, cz - az
    pu = dv * e2z - dz * e2v
    pv = dz * e2u - du * e2z
    pz = du * e2v - dv * e2u
    det = e1u * pu + e1v * pv + e1z * pz
    if abs(det) < _EPS:
        return -1.0
    inv = 1.0 / det
    tu, tv, tz = ou - au, ov - av, oz - az
    b1 = (tu * pu + tv * pv + tz * pz) * inv
    if b1 < -1e-9 or b1 > 1.0 + 1e-9:
        return -1.0
    qu = tv * e1z - tz * e1v
    qv = tz * e1u - tu * e1z
    qz = tu * e1v - tv * e1u
    b2 = (du * qu + dv * qv + dz * qz) * inv
    if b2 < -1e-9 or b1 + b2 > 1.0 + 1e-9:
        return -1.0
    return (e2u * qu + e2v * qv + e2z * qz) * inv


@njit(cache=True)
def _trace_one(ou, ov, oz, du, dv, dz, H, cmin, cmax, zlo, zhi, tmin):
    """Nearest hit of one ray (grid units) with t > tmin → (t, j, i, k) or (-1, -1, -1, -1)."""
    n = H.shape[0]
    hi = n - 1.0
    t0, t1 = tmin, _INF
    # slab clipping against the bounding box [0, n-1]^2 x [zlo, zhi]
    for o, d, lo, up in ((ou, du, 0.0, hi), (ov, dv, 0.0, hi), (oz, dz, zlo, zhi)):
        if abs(d) < _EPS:
            if o < lo or o > up:
                return -1.0, -1, -1, -1
        else:
            ta, tb = (lo - o) / d, (up - o) / d
            if ta > tb:
                ta, tb = tb, ta
            t0 = max(t0, ta)
            t1 = min(t1, tb)
    if t0 > t1:
        return -1.0, -1, -1, -1
    pu, pv = ou + t0 * du, ov + t0 * dv
    i = min(max(int(math.floor(pu)), 0), n - 2)
    j = min(max(int(math.floor(pv)), 0), n - 2)
    if du > _EPS:
        si, tmu, tdu = 1, (i + 1 - ou) / du, 1.0 / du
    elif du < -_EPS:
        si, tmu, tdu = -1, (i - ou) / du, -1.0 / du
    else:
        si, tmu, tdu = 0, _INF, _INF
    if dv > _EPS:
        sj, tmv, tdv = 1, (j + 1 - ov) / dv, 1.0 / dv
    elif dv < -_EPS:
        sj, tmv, tdv = -1, (j - ov) / dv, -1.0 / dv
    else:
        sj, tmv, tdv = 0, _INF, _INF
    tc0 = t0
    while True:
        tc1 = min(min(tmu, tmv), t1)
        za, zb = oz + tc0 * dz, oz + tc1 * dz
        if max(za, zb) >= cmin[j, i] - 1e-9 and min(za, zb) <= cmax[j, i] + 1e-9:
            hA, hB, hC, hD = H[j, i], H[j, i + 1], H[j + 1, i + 1], H[j + 1, i]
            best, bk = _INF, -1
            t = _tri(ou, ov, oz, du, dv, dz, i, j, hA, i + 1, j, hB, i + 1, j + 1, hC)
            if t > tmin and t < best:
                best, bk = t, 0
            t = _tri(ou, ov, oz, du, dv, dz, i, j, hA, i + 1, j + 1, hC, i, j + 1, hD)
            if t > tmin and t < best:
                best, bk = t, 1
            if bk >= 0:
                return best, j, i, bk
        if tc1 >= t1:
            break
        if tmu < tmv:
            i += si
            tc0 = tmu
            tmu += tdu
        else:
            j += sj
            tc0 = tmv
            tmv += tdv
        if i < 0 or i > n - 2 or j < 0 or j > n - 2:
            break
    return -1.0, -1, -1, -1


@njit(cache=True)
def trace_rays(origins, dirs, H, cmin, cmax, spacing, normals, sun, shadow_eps):
    """Cast primary rays and, from every hit, a shadow ray toward the sun.

    Parameters
    ----------
    origins, dirs : (N, 3) float64
        Ray origins and directions in the maplet frame (metres; directions need not be unit).
    H, cmin, cmax, normals
        From :class:`~.maplet_mesh.MapletMesh`.
    spacing : float
        Grid spacing, m.
    sun : (3,) float64
        Unit vector toward the sun, maplet frame; a zero vector disables the shadow rays.
    shadow_eps : float
        Offset of the shadow ray origin along the facet normal, m.

    Returns
    -------
    hit : (N,) bool
    points : (N, 3) hit points, maplet frame (NaN where no hit)
    nrm : (N, 3) facet normals at the hits
    shadow : (N,) bool, the shadow ray hit the maplet
    """
    N = origins.shape[0]
    c = (H.shape[0] - 1) / 2.0
    hit = np.zeros(N, np.bool_)
    shadow = np.zeros(N, np.bool_)
    pts = np.full((N, 3), np.nan)
    nrm = np.full((N, 3), np.nan)
    zlo, zhi = cmin.min(), cmax.max()
    do_shadow = sun[0] != 0.0 or sun[1] != 0.0 or sun[2] != 0.0
    for r in range(N):
        ou, ov, oz = origins[r, 0] / spacing + c, origins[r, 1] / spacing + c, origins[r, 2]
        du, dv, dz = dirs[r, 0] / spacing, dirs[r, 1] / spacing, dirs[r, 2]
        t, j, i, k = _trace_one(ou, ov, oz, du, dv, dz, H, cmin, cmax, zlo, zhi, 0.0)
        if t < 0:
            continue
        hit[r] = True
        for a in range(3):
            pts[r, a] = origins[r, a] + t * dirs[r, a]
            nrm[r, a] = normals[j, i, k, a]
        if do_shadow:
            sx = pts[r, 0] + shadow_eps * nrm[r, 0]
            sy = pts[r, 1] + shadow_eps * nrm[r, 1]
            sz = pts[r, 2] + shadow_eps * nrm[r, 2]
            ts, _, _, _ = _trace_one(sx / spacing + c, sy / spacing + c, sz,
                                     sun[0] / spacing, sun[1] / spacing, sun[2], H, cmin, cmax, zlo, zhi, 0.0)
            shadow[r] = ts > 0
    return hit, pts, nrm, shadow


@njit(cache=True)
def _bilinear1(g, u, v):
    n1, n0 = g.shape[0] - 1, g.shape[1] - 1
    u = min(max(u, 0.0), n0)
    v = min(max(v, 0.0), n1)
    i0 = min(int(u), n0 - 1)
    j0 = min(int(v), n1 - 1)
    fu, fv = u - i0, v - j0
    return ((1 - fu) * (1 - fv) * g[j0, i0] + fu * (1 - fv) * g[j0, i0 + 1]
            + (1 - fu) * fv * g[j0 + 1, i0] + fu * fv * g[j0 + 1, i0 + 1])


@njit(cache=True)
def shade_pixels(origin, dirs, k2, H, cmin, cmax, spacing, normals, albedo, sun, shadow_rays, alpha0, ls_weight,
                 shadow_eps):
    """Fused Retina synthetic image: trace, shadow-test and McEwen-shade k2 rays per pixel, average them.

    ``dirs`` (P·k2, 3) holds the k2 sub-pixel rays of pixel p at rows p·k2 … p·k2 + k2 − 1 (maplet frame);
    all rays start at ``origin``. Returns the pixel means (P,), the hit count (P,) and the number of hit
    samples in cast shadow (P,). Same per-ray results as :func:`trace_rays` + ``mcewen_relative``.
    """
    P = dirs.shape[0] // k2
    c = (H.shape[0] - 1) / 2.0
    zlo, zhi = cmin.min(), cmax.max()
    value = np.zeros(P)
    nhit = np.zeros(P, np.int64)
    nshadow = np.zeros(P, np.int64)
    ou, ov, oz = origin[0] / spacing + c, origin[1] / spacing + c, origin[2]
    for p in range(P):
        acc = 0.0
        for q in range(k2):
            r = p * k2 + q
            dx, dy, dz = dirs[r, 0], dirs[r, 1], dirs[r, 2]
            if not (dx == dx and dy == dy and dz == dz):
                continue
            t, j, i, k = _trace_one(ou, ov, oz, dx / spacing, dy / spacing, dz, H, cmin, cmax, zlo, zhi, 0.0)
            if t < 0:
                continue
            nhit[p] += 1
            px, py, pz = origin[0] + t * dx, origin[1] + t * dy, origin[2] + t * dz
            nx, ny, nz = normals[j, i, k, 0], normals[j, i, k, 1], normals[j, i, k, 2]
            cos_i = nx * sun[0] + ny * sun[1] + nz * sun[2]
            if cos_i <= 0.0:
                continue
            if shadow_rays:
                sx, sy, sz = px + shadow_eps * nx, py + shadow_eps * ny, pz + shadow_eps * nz
                ts, _, _, _ = _trace_one(sx / spacing + c, sy / spacing + c, sz, sun[0] / spacing, sun[1] / spacing,
                                         sun[2], H, cmin, cmax, zlo, zhi, 0.0)
                if ts > 0:
                    nshadow[p] += 1
                    continue
            vx, vy, vz = origin[0] - px, origin[1] - py, origin[2] - pz
            vn = math.sqrt(vx * vx + vy * vy + vz * vz)
            vx, vy, vz = vx / vn, vy / vn, vz / vn
            cos_r = nx * vx + ny * vy + nz * vz
            cs = min(max(vx * sun[0] + vy * sun[1] + vz * sun[2], -1.0), 1.0)
            a = _bilinear1(albedo, px / spacing + c, py / spacing + c)
            acc += mcewen_scalar(cos_i, cos_r, math.acos(cs), a, alpha0, ls_weight)
        value[p] = acc / k2
    return value, nhit, nshadow


def trace_bruteforce(mesh, origins, dirs, chunk: int = 256):
    """Plain-numpy reference: nearest hit of every ray against every facet (Möller–Trumbore).

    Returns ``(hit (N,), t (N,), face (N,))`` with faces numbered as
    :meth:`~.maplet_mesh.MapletMesh.vertices_faces`.
    """
    V, F = mesh.vertices_faces()
    A, B, C = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    e1, e2 = B - A, C - A
    origins = np.asarray(origins, float)
    dirs = np.asarray(dirs, float)
    N = len(origins)
    t_best = np.full(N, np.inf)
    f_best = np.full(N, -1)
    for a in range(0, N, chunk):
        o, d = origins[a:a + chunk, None, :], dirs[a:a + chunk, None, :]
        p = np.cross(d, e2[None])
        det = np.einsum("rfk,fk->rf", p, e1)
        ok = np.abs(det) > 1e-15
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        tv = o - A[None]
        b1 = np.einsum("rfk,rfk->rf", tv, p) * inv
        q = np.cross(tv, e1[None])
        b2 = np.einsum("rfk,rfk->rf", np.broadcast_to(d, q.shape), q) * inv
        t = np.einsum("fk,rfk->rf", e2, q) * inv
        good = ok & (b1 >= -1e-9) & (b1 <= 1 + 1e-9) & (b2 >= -1e-9) & (b1 + b2 <= 1 + 1e-9) & (t > 0)
        t = np.where(good, t, np.inf)
        k = np.argmin(t, axis=1)
        t_best[a:a + chunk] = t[np.arange(len(k)), k]
        f_best[a:a + chunk] = np.where(np.isfinite(t_best[a:a + chunk]), k, -1)
    hit = np.isfinite(t_best)
    return hit, np.where(hit, t_best, np.nan), f_best


def trace_rays_numpy(mesh, origins, dirs, sun, shadow_eps):
    """Plain-numpy counterpart of :func:`trace_rays` (brute force over every facet); same outputs."""
    hit, t, face = trace_bruteforce(mesh, origins, dirs)
    N = len(origins)
    pts = np.full((N, 3), np.nan)
    nrm = np.full((N, 3), np.nan)
    pts[hit] = origins[hit] + t[hit, None] * dirs[hit]
    n_cells = mesh.n - 1
    f = face[hit]
    nrm[hit] = mesh.normals[(f // 2) // n_cells, (f // 2) % n_cells, f % 2]
    shadow = np.zeros(N, bool)
    if np.any(sun != 0) and hit.any():
        hs, _, _ = trace_bruteforce(mesh, pts[hit] + shadow_eps * nrm[hit], np.tile(sun, (hit.sum(), 1)))
        shadow[hit] = hs
    return hit, pts, nrm, shadow
