r"""Ray–maplet intersection and shadow rays ("single-bounce" ray tracing, Retina synthetic image step 3–4).

Kernels (numba) walk the maplet's cell grid with a 2-D DDA (Amanatides & Woo; see :mod:`.maplet_mesh`)
on two levels — 8 × 8-cell blocks first, skipping every block whose height interval the ray misses, then
the cells of the others — and test the two triangles of each candidate cell with the Möller–Trumbore
algorithm. Work is done in *grid units* (u = column index, v = row index, z in metres): an affine change
of coordinates keeps the ray parameter t, so hit distances are metric. :func:`shade_pixels` fuses tracing,
shadow rays, McEwen shading (eqs. 5–8) and supersampling for the synthetic image; :func:`shade_pinhole`
also makes the lines of sight of a distortion-free camera (inverse of eqs. 3–4) inside the kernel.
:mod:`.raytrace_numpy` holds the plain-numpy reference (every ray against every facet); the tests use it
as the oracle and the benchmark as the speed baseline.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from estimators.onboard_photometry import beta_scalar, mcewen_beta_scalar

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


BLOCK = 8  # cells per side of a block of the two-level grid


@njit(cache=True)
def block_bounds(cmin, cmax, B):
    """Min / max height of every B × B block of cells (the coarse level of the two-level grid)."""
    nc = cmin.shape[0]
    nb = (nc + B - 1) // B
    bmin = np.full((nb, nb), np.inf)
    bmax = np.full((nb, nb), -np.inf)
    for j in range(nc):
        for i in range(nc):
            J, I = j // B, i // B
            bmin[J, I] = min(bmin[J, I], cmin[j, i])
            bmax[J, I] = max(bmax[J, I], cmax[j, i])
    return bmin, bmax


@njit(cache=True, inline="always")
def _dda_setup(o, d, idx, size):
    """DDA step, first crossing and crossing interval along one axis for cells of ``size``."""
    if d > _EPS:
        return 1, ((idx + 1) * size - o) / d, size / d
    if d < -_EPS:
        return -1, (idx * size - o) / d, -size / d
    return 0, _INF, _INF


@njit(cache=True)
def _trace_block(ou, ov, oz, du, dv, dz, H, cmin, cmax, tmin, ta, tb, i_lo, i_hi, j_lo, j_hi):
    """Cell DDA inside one block (cells i_lo..i_hi, j_lo..j_hi) over ray parameters [ta, tb]."""
    pu, pv = ou + ta * du, ov + ta * dv
    i = min(max(int(math.floor(pu)), i_lo), i_hi)
    j = min(max(int(math.floor(pv)), j_lo), j_hi)
    si, tmu, tdu = _dda_setup(ou, du, i, 1.0)
    sj, tmv, tdv = _dda_setup(ov, dv, j, 1.0)
    tc0 = ta
    while True:
        tc1 = min(min(tmu, tmv), tb)
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
        if tc1 >= tb:
            break
        if tmu < tmv:
            i += si
            tc0 = tmu
            tmu += tdu
        else:
            j += sj
            tc0 = tmv
            tmv += tdv
        if i < i_lo or i > i_hi or j < j_lo or j > j_hi:
            break
    return -1.0, -1, -1, -1


@njit(cache=True)
def _trace_one(ou, ov, oz, du, dv, dz, H, cmin, cmax, bmin, bmax, B, zlo, zhi, tmin):
    """Nearest hit of one ray (grid units) with t > tmin → (t, j, i, k) or (-1, -1, -1, -1).

    Two-level walk: a DDA over B × B blocks of cells skips every block whose height interval the ray
    misses; inside the others a DDA over cells tests the two triangles of each overlapping cell. Blocks
    and cells are visited in order of t, so the first hit is the nearest.
    """
    nc = H.shape[0] - 1
    hi = float(nc)
    t0, t1 = tmin, _INF
    # slab clipping against the bounding box [0, n-1]^2 x [zlo, zhi]
    if abs(du) < _EPS:
        if ou < 0.0 or ou > hi:
            return -1.0, -1, -1, -1
    else:
        ta, tb = (0.0 - ou) / du, (hi - ou) / du
        if ta > tb:
            ta, tb = tb, ta
        t0, t1 = max(t0, ta), min(t1, tb)
    if abs(dv) < _EPS:
        if ov < 0.0 or ov > hi:
            return -1.0, -1, -1, -1
    else:
        ta, tb = (0.0 - ov) / dv, (hi - ov) / dv
        if ta > tb:
            ta, tb = tb, ta
        t0, t1 = max(t0, ta), min(t1, tb)
    if abs(dz) < _EPS:
        if oz < zlo or oz > zhi:
            return -1.0, -1, -1, -1
    else:
        ta, tb = (zlo - oz) / dz, (zhi - oz) / dz
        if ta > tb:
            ta, tb = tb, ta
        t0, t1 = max(t0, ta), min(t1, tb)
    if t0 > t1:
        return -1.0, -1, -1, -1
    nb = bmin.shape[0]
    fB = float(B)
    I = min(max(int(math.floor((ou + t0 * du) / fB)), 0), nb - 1)
    J = min(max(int(math.floor((ov + t0 * dv) / fB)), 0), nb - 1)
    sI, tmu, tdu = _dda_setup(ou, du, I, fB)
    sJ, tmv, tdv = _dda_setup(ov, dv, J, fB)
    tc0 = t0
    while True:
        tc1 = min(min(tmu, tmv), t1)
        za, zb = oz + tc0 * dz, oz + tc1 * dz
        if max(za, zb) >= bmin[J, I] - 1e-9 and min(za, zb) <= bmax[J, I] + 1e-9:
            t, j, i, k = _trace_block(ou, ov, oz, du, dv, dz, H, cmin, cmax, tmin, tc0, tc1,
                                      I * B, min(I * B + B, nc) - 1, J * B, min(J * B + B, nc) - 1)
            if t >= 0.0:
                return t, j, i, k
        if tc1 >= t1:
            break
        if tmu < tmv:
            I += sI
            tc0 = tmu
            tmu += tdu
        else:
            J += sJ
            tc0 = tmv
            tmv += tdv
        if I < 0 or I >= nb or J < 0 or J >= nb:
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
    bmin, bmax = block_bounds(cmin, cmax, BLOCK)
    do_shadow = sun[0] != 0.0 or sun[1] != 0.0 or sun[2] != 0.0
    for r in range(N):
        ou, ov, oz = origins[r, 0] / spacing + c, origins[r, 1] / spacing + c, origins[r, 2]
        du, dv, dz = dirs[r, 0] / spacing, dirs[r, 1] / spacing, dirs[r, 2]
        t, j, i, k = _trace_one(ou, ov, oz, du, dv, dz, H, cmin, cmax, bmin, bmax, BLOCK, zlo, zhi, 0.0)
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
                                     sun[0] / spacing, sun[1] / spacing, sun[2], H, cmin, cmax, bmin, bmax, BLOCK,
                                     zlo, zhi, 0.0)
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


@njit(cache=True, inline="always")
def shade_lit_point(origin, px, py, pz, nx, ny, nz, cos_i, sun, albedo, spacing, c, alpha0, L_table, ls_weight):
    """McEwen brightness (eq. 5-8) of a sunlit maplet point p with facet normal n seen from ``origin``:
    emission and phase from the view direction, albedo bilinear on the maplet grid."""
    vx, vy, vz = origin[0] - px, origin[1] - py, origin[2] - pz
    vn = math.sqrt(vx * vx + vy * vy + vz * vz)
    vx, vy, vz = vx / vn, vy / vn, vz / vn
    cos_r = nx * vx + ny * vy + nz * vz
    cs = min(max(vx * sun[0] + vy * sun[1] + vz * sun[2], -1.0), 1.0)
    a = _bilinear1(albedo, px / spacing + c, py / spacing + c)
    return mcewen_beta_scalar(cos_i, cos_r, beta_scalar(math.acos(cs), alpha0, L_table), a, ls_weight)


@njit(cache=True, inline="always")
def _shade_sample(origin, ou, ov, oz, dx, dy, dz, c, H, cmin, cmax, bmin, bmax, zlo, zhi, spacing, normals, albedo,
                  sun, shadow_rays, alpha0, L_table, ls_weight, shadow_eps):
    """One sub-pixel ray: (hit, in cast shadow, McEwen value) — trace, shadow ray, eqs. 5–8."""
    t, j, i, k = _trace_one(ou, ov, oz, dx / spacing, dy / spacing, dz, H, cmin, cmax, bmin, bmax, BLOCK,
                            zlo, zhi, 0.0)
    if t < 0:
        return False, False, 0.0
    px, py, pz = origin[0] + t * dx, origin[1] + t * dy, origin[2] + t * dz
    nx, ny, nz = normals[j, i, k, 0], normals[j, i, k, 1], normals[j, i, k, 2]
    cos_i = nx * sun[0] + ny * sun[1] + nz * sun[2]
    if cos_i <= 0.0:
        return True, False, 0.0
    if shadow_rays:
        sx, sy, sz = px + shadow_eps * nx, py + shadow_eps * ny, pz + shadow_eps * nz
        ts, _, _, _ = _trace_one(sx / spacing + c, sy / spacing + c, sz, sun[0] / spacing, sun[1] / spacing,
                                 sun[2], H, cmin, cmax, bmin, bmax, BLOCK, zlo, zhi, 0.0)
        if ts > 0:
            return True, True, 0.0
    return True, False, shade_lit_point(origin, px, py, pz, nx, ny, nz, cos_i, sun, albedo, spacing, c, alpha0,
                                        L_table, ls_weight)


@njit(cache=True)
def shade_pixels(origin, dirs, k2, H, cmin, cmax, bmin, bmax, spacing, normals, albedo, sun, shadow_rays, alpha0,
                 L_table, ls_weight, shadow_eps):
    """Fused Retina synthetic image: trace, shadow-test and McEwen-shade k2 rays per pixel, average them.

    ``dirs`` (P·k2, 3) holds the k2 sub-pixel rays of pixel p at rows p·k2 … p·k2 + k2 − 1 (maplet frame);
    all rays start at ``origin``; NaN rows are skipped. ``bmin``/``bmax`` come from :func:`block_bounds`.
    Returns the pixel means (P,), the hit count (P,) and the number of hit samples in cast shadow (P,).
    Same per-ray results as :func:`trace_rays` + ``mcewen_relative``.
    """
    P = dirs.shape[0] // k2
    c = (H.shape[0] - 1) / 2.0
    value = np.zeros(P)
    nhit = np.zeros(P, np.int64)
    nshadow = np.zeros(P, np.int64)
    zlo, zhi = bmin.min(), bmax.max()
    ou, ov, oz = origin[0] / spacing + c, origin[1] / spacing + c, origin[2]
    for p in range(P):
        acc = 0.0
        for q in range(k2):
            r = p * k2 + q
            dx, dy, dz = dirs[r, 0], dirs[r, 1], dirs[r, 2]
            if not (dx == dx and dy == dy and dz == dz):
                continue
            h, s, v = _shade_sample(origin, ou, ov, oz, dx, dy, dz, c, H, cmin, cmax, bmin, bmax, zlo, zhi, spacing,
                                    normals, albedo, sun, shadow_rays, alpha0, L_table, ls_weight, shadow_eps)
            nhit[p] += h
            nshadow[p] += s
            acc += v
        value[p] = acc / k2
    return value, nhit, nshadow


@njit(cache=True)
def shade_pinhole(origin, R_m_from_c, Kinv, s_min, l_min, w, h, k, H, cmin, cmax, bmin, bmax, spacing, normals,
                  albedo, sun, shadow_rays, alpha0, L_table, ls_weight, shadow_eps):
    """:func:`shade_pixels` with the rays of a distortion-free camera made in the kernel.

    Sub-pixel sample (ix, iy) of pixel (s, l) sits at (s + (ix + ½)/k − ½, l + (iy + ½)/k − ½); its line of
    sight is ``R_m_from_c · normalize(K⁻¹ (s, l, 1))`` (eqs. 3–4 inverted; ``Kinv`` the 3 × 3 inverse pixel
    map). Pixels are returned row-major over (l, s): w·h values.
    """
    c = (H.shape[0] - 1) / 2.0
    P = w * h
    value = np.zeros(P)
    nhit = np.zeros(P, np.int64)
    nshadow = np.zeros(P, np.int64)
    zlo, zhi = bmin.min(), bmax.max()
    ou, ov, oz = origin[0] / spacing + c, origin[1] / spacing + c, origin[2]
    for y in range(h):
        for x in range(w):
            p = y * w + x
            acc = 0.0
            for iy in range(k):
                ls = l_min + y + (iy + 0.5) / k - 0.5
                for ix in range(k):
                    ss = s_min + x + (ix + 0.5) / k - 0.5
                    cx = Kinv[0, 0] * ss + Kinv[0, 1] * ls + Kinv[0, 2]
                    cy = Kinv[1, 0] * ss + Kinv[1, 1] * ls + Kinv[1, 2]
                    nrm = math.sqrt(cx * cx + cy * cy + 1.0)
                    cx, cy, cz = cx / nrm, cy / nrm, 1.0 / nrm
                    dx = R_m_from_c[0, 0] * cx + R_m_from_c[0, 1] * cy + R_m_from_c[0, 2] * cz
                    dy = R_m_from_c[1, 0] * cx + R_m_from_c[1, 1] * cy + R_m_from_c[1, 2] * cz
                    dz = R_m_from_c[2, 0] * cx + R_m_from_c[2, 1] * cy + R_m_from_c[2, 2] * cz
                    hh, s, v = _shade_sample(origin, ou, ov, oz, dx, dy, dz, c, H, cmin, cmax, bmin, bmax, zlo, zhi,
                                             spacing, normals, albedo, sun, shadow_rays, alpha0, L_table, ls_weight,
                                             shadow_eps)
                    nhit[p] += hh
                    nshadow[p] += s
                    acc += v
            value[p] = acc / (k * k)
    return value, nhit, nshadow
