r"""Fast synthetic image for a distortion-free camera: z-buffer rasterisation of the maplet facets, and a
sun-view facet-id map that settles most shadow tests without a shadow ray (Retina synthetic image,
steps 2–4, same result as the ray caster of :mod:`.raytrace`).

Primary visibility. The maplet is a height field of planar triangles. Under a pinhole camera (eqs. 1–4
without distortion) a triangle projects to a triangle, so "the line of sight through sample (s, l) hits
facet f" (Retina's ray casting) is the same statement as "(s, l) lies inside f's projection". Every facet
is scan-converted over the sub-pixel samples its projection covers; of the facets covering a sample the
z-buffer keeps the one with the smallest ray parameter t = n̂·(A − o) / n̂·d (the exact ray–plane
intersection). Cost O(facets + samples) instead of a grid walk per sample; the hit point o + t d, its
facet normal, the albedo and McEwen's law (eqs. 5–8) are then exactly those of the ray caster.

Shadows. The sun is at infinity, so all shadow rays are parallel. One sweep per template over a grid
aligned with the sun azimuth (``grid_step`` maplet cells apart, :func:`shadow_gap_grid`) gives, along
each line from the sun side, the shadow height S_q = max(z_q, S_{q+1} − m·step) (m = tan of the sun
elevation, z on the maplet's own triangles; each line only over the stretch that crosses the maplet)
and the gap G = S − z (> 0: in cast shadow), kept as int8 states for the shading loop. A sample whose
four surrounding sweep points agree (all lit or all shadowed) takes their state; where they disagree (a
shadow edge crosses) or lie off the maplet, the exact grid-walk shadow ray of :mod:`.raytrace` is cast.
Differences from casting every shadow ray: a shadow (or lit gap) narrower than the sweep spacing that
passes between the four points is missed, and S between sweep points on a line is sampled, not
maximised; at a shared facet edge the two paths may pick different, equally near facets. The tests bound
the difference (identical pixels away from shadow edges; measured shifts within 0.01 px).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from estimators.onboard_photometry import beta_scalar, mcewen_beta_scalar
from estimators.retina.raytrace import BLOCK, _bilinear1, _trace_one

_TOL = 1e-9  # inclusive barycentric tolerance: samples on a shared edge belong to both facets


@njit(cache=True, inline="always")
def _edge(ax, ay, bx, by, px, py):
    return (bx - ax) * (py - ay) - (by - ay) * (px - ax)


@njit(cache=True, inline="always")
def _corner(j, i, kk, q):
    """Grid indices (row, column) of corner q of triangle kk of cell (j, i) (maplet_mesh's split)."""
    if q == 0:
        return j, i
    if q == 1:
        return (j, i + 1) if kk == 0 else (j + 1, i + 1)
    return (j + 1, i + 1) if kk == 0 else (j + 1, i)


@njit(cache=True, inline="always")
def _height(H, u, v):
    """Height of the triangulated maplet at grid coordinates (u = column, v = row); NaN outside."""
    n1 = H.shape[0] - 1
    if not (0.0 <= u <= n1 and 0.0 <= v <= n1):
        return np.nan
    i = min(int(u), n1 - 1)
    j = min(int(v), n1 - 1)
    fu, fv = u - i, v - j
    if fu >= fv:  # tri 0: (j, i), (j, i+1), (j+1, i+1)
        return H[j, i] + fu * (H[j, i + 1] - H[j, i]) + fv * (H[j + 1, i + 1] - H[j, i + 1])
    return H[j, i] + fv * (H[j + 1, i] - H[j, i]) + fu * (H[j + 1, i + 1] - H[j + 1, i])


@njit(cache=True)
def shadow_gap_grid(H, spacing, sun, step):
    """Shadow height gap on a grid aligned with the sun azimuth (module docstring).

    Grid point (r, q) sits at perpendicular offset ``(r − r0) step`` and along-sun offset ``(q − q0) step``
    (grid units) from the maplet centre. Along every line, from the sun side, S_q = max(z_q, S_{q+1} − m·step)
    (m: rise of the sun ray per grid unit); G = S − z (> 0: cast shadow), NaN off the maplet. Returns
    ``(G, frame)`` with frame = (dx, dy, r0, q0, step): the unit azimuth (grid units) and the offsets.
    """
    n = H.shape[0]
    c = (n - 1) / 2.0
    hxy = math.sqrt(sun[0] * sun[0] + sun[1] * sun[1])
    if hxy < 1e-12:
        dx, dy, m = 1.0, 0.0, np.inf  # sun at the zenith: a height field casts no shadow
    else:
        dx, dy, m = sun[0] / hxy, sun[1] / hxy, sun[2] / hxy * spacing
    half = c * math.sqrt(2.0)
    nr = int(math.ceil(2 * half / step)) + 1
    r0 = q0 = (nr - 1) / 2.0
    G = np.full((nr, nr), np.nan)
    n1 = float(n - 1)
    for r in range(nr):
        pr = (r - r0) * step
        # the line's points (u, v) = (c − pr·dy, c + pr·dx) + pq·(dx, dy) on the maplet [0, n−1]²: a
        # conservative q range (one point of margin each side; the points outside it are off the maplet)
        lo, hi = -np.inf, np.inf
        for base, d in ((c - pr * dy, dx), (c + pr * dx, dy)):
            if abs(d) < 1e-12:
                if base < -1e-9 or base > n1 + 1e-9:
                    lo, hi = 1.0, 0.0
            else:
                a, b = (0.0 - base) / d, (n1 - base) / d
                lo, hi = max(lo, min(a, b)), min(hi, max(a, b))
        if not lo <= hi:
            continue
        q_lo = max(int(math.floor(lo / step + q0)) - 1, 0)
        q_hi = min(int(math.ceil(hi / step + q0)) + 1, nr - 1)
        S = -np.inf
        for q in range(q_hi, q_lo - 1, -1):
            pq = (q - q0) * step
            u = c + pq * dx - pr * dy
            v = c + pq * dy + pr * dx
            z = _height(H, u, v)
            if z != z:
                if S > -np.inf:
                    break  # left the (convex) maplet on the far side
                continue
            S = max(z, S - m * step)
            G[r, q] = S - z
    return G, np.array([dx, dy, r0, q0, step])


@njit(cache=True)
def shadow_states(G, tol):
    """The sweep grid as int8 states: 1 cast shadow (G > tol), 0 lit, 2 off the maplet (G NaN). The
    shading loop reads these (an eighth of G's memory) instead of G."""
    st = np.empty(G.shape, np.int8)
    for r in range(G.shape[0]):
        for q in range(G.shape[1]):
            g = G[r, q]
            st[r, q] = 2 if g != g else (1 if g > tol else 0)
    return st


@njit(cache=True, inline="always")
def _shadow_weight(st, frame, c, u, v):
    """Bilinear interpolation, at grid position (u, v), of the cast-shadow indicator (``shadow_states``)
    of the four sun-grid points around it (≥ ½: in shadow); −1 off the grid or next to its edge."""
    pu, pv = u - c, v - c
    q = (pu * frame[0] + pv * frame[1]) / frame[4] + frame[3]
    r = (-pu * frame[1] + pv * frame[0]) / frame[4] + frame[2]
    iq, ir = int(math.floor(q)), int(math.floor(r))
    nr = st.shape[0]
    if iq < 0 or ir < 0 or iq + 1 >= nr or ir + 1 >= nr:
        return -1.0
    fq, fr = q - iq, r - ir
    if fq == 0.0 or fr == 0.0:
        fq, fr = max(fq, 1e-9), max(fr, 1e-9)  # all four points count
    g00, g01, g10, g11 = st[ir, iq], st[ir, iq + 1], st[ir + 1, iq], st[ir + 1, iq + 1]
    if g00 == 2 or g01 == 2 or g10 == 2 or g11 == 2:
        return -1.0
    return ((1 - fr) * ((1 - fq) * (g00 == 1) + fq * (g01 == 1))
            + fr * ((1 - fq) * (g10 == 1) + fq * (g11 == 1)))


@njit(cache=True)
def raster_pinhole(origin, R_m_from_c, K, Kinv, s_min, l_min, w, h, k, H, cmin, cmax, bmin, bmax, spacing, normals,
                   albedo, sun, shadow_rays, alpha0, L_table, ls_weight, shadow_eps, grid_step):
    """Rasterised equivalent of :func:`~.raytrace.shade_pinhole` (module docstring), same arguments plus
    ``K`` (3 × 3 pixel map) and ``grid_step`` (sweep spacing, maplet cells).

    Returns ``(value (w·h,), nhit, nshadow, n_shadow_rays, ok)``: pixel means, hit and cast-shadow sample
    counts, the number of full shadow rays cast, and False when a maplet point is not in front of the
    camera (nothing computed; use the ray caster).
    """
    n = H.shape[0]
    c = (n - 1) / 2.0
    W, Hs = w * k, h * k
    P = w * h
    value = np.zeros(P)
    nhit = np.zeros(P, np.int64)
    nshadow = np.zeros(P, np.int64)
    # project the grid points to sample coordinates X = (s − s_min + ½) k − ½ (sample centres at integers)
    X = np.empty((n, n))
    Y = np.empty((n, n))
    for j in range(n):
        for i in range(n):
            qx, qy, qz = (i - c) * spacing - origin[0], (j - c) * spacing - origin[1], H[j, i] - origin[2]
            x = R_m_from_c[0, 0] * qx + R_m_from_c[1, 0] * qy + R_m_from_c[2, 0] * qz
            y = R_m_from_c[0, 1] * qx + R_m_from_c[1, 1] * qy + R_m_from_c[2, 1] * qz
            z = R_m_from_c[0, 2] * qx + R_m_from_c[1, 2] * qy + R_m_from_c[2, 2] * qz
            if not z > 0.0:
                return value, nhit, nshadow, 0, False
            s = (K[0, 0] * x + K[0, 1] * y + K[0, 2] * z) / z
            l = (K[1, 0] * x + K[1, 1] * y + K[1, 2] * z) / z
            X[j, i] = (s - s_min + 0.5) * k - 0.5
            Y[j, i] = (l - l_min + 0.5) * k - 0.5
    # line of sight of every sample (maplet frame), as shade_pinhole makes them
    D = np.empty((Hs, W, 3))
    for yy in range(Hs):
        ls = l_min + (yy + 0.5) / k - 0.5
        for xx in range(W):
            ss = s_min + (xx + 0.5) / k - 0.5
            cx = Kinv[0, 0] * ss + Kinv[0, 1] * ls + Kinv[0, 2]
            cy = Kinv[1, 0] * ss + Kinv[1, 1] * ls + Kinv[1, 2]
            nr = math.sqrt(cx * cx + cy * cy + 1.0)
            cx, cy, cz = cx / nr, cy / nr, 1.0 / nr
            for a in range(3):
                D[yy, xx, a] = R_m_from_c[a, 0] * cx + R_m_from_c[a, 1] * cy + R_m_from_c[a, 2] * cz
    zbuf = np.full((Hs, W), np.inf)
    face = np.full((Hs, W), -1, np.int64)
    for j in range(n - 1):
        for i in range(n - 1):
            for kk in range(2):
                j0, i0 = _corner(j, i, kk, 0)
                j1, i1 = _corner(j, i, kk, 1)
                j2, i2 = _corner(j, i, kk, 2)
                ax, ay, bx, by, cx, cy = X[j0, i0], Y[j0, i0], X[j1, i1], Y[j1, i1], X[j2, i2], Y[j2, i2]
                area = _edge(ax, ay, bx, by, cx, cy)
                if abs(area) < 1e-14:
                    continue  # edge-on: no line of sight enters it
                x0 = max(int(math.ceil(min(ax, min(bx, cx)) - 1e-9)), 0)
                x1 = min(int(math.floor(max(ax, max(bx, cx)) + 1e-9)), W - 1)
                y0 = max(int(math.ceil(min(ay, min(by, cy)) - 1e-9)), 0)
                y1 = min(int(math.floor(max(ay, max(by, cy)) + 1e-9)), Hs - 1)
                if x0 > x1 or y0 > y1:
                    continue
                nx, ny, nz = normals[j, i, kk, 0], normals[j, i, kk, 1], normals[j, i, kk, 2]
                num = (nx * ((i0 - c) * spacing - origin[0]) + ny * ((j0 - c) * spacing - origin[1])
                       + nz * (H[j0, i0] - origin[2]))
                f = 2 * (j * (n - 1) + i) + kk
                for yy in range(y0, y1 + 1):
                    for xx in range(x0, x1 + 1):
                        w0 = _edge(bx, by, cx, cy, xx, yy) / area
                        w1 = _edge(cx, cy, ax, ay, xx, yy) / area
                        if w0 < -_TOL or w1 < -_TOL or 1.0 - w0 - w1 < -_TOL:
                            continue
                        den = nx * D[yy, xx, 0] + ny * D[yy, xx, 1] + nz * D[yy, xx, 2]
                        if abs(den) < 1e-15:
                            continue
                        t = num / den
                        if t > 0.0 and t < zbuf[yy, xx]:
                            zbuf[yy, xx] = t
                            face[yy, xx] = f
    do_shadow = shadow_rays and (sun[0] != 0.0 or sun[1] != 0.0 or sun[2] != 0.0)
    if do_shadow:
        G, gframe = shadow_gap_grid(H, spacing, sun, grid_step)
        st = shadow_states(G, shadow_eps)
    else:
        st, gframe = np.zeros((1, 1), np.int8), np.array([1.0, 0.0, 0.0, 0.0, 1.0])
    zlo, zhi = bmin.min(), bmax.max()
    su, sv, sw = sun[0] / spacing, sun[1] / spacing, sun[2]
    n_rays = 0
    nf = normals.reshape((-1, 3))  # facet f = 2 (j (n−1) + i) + kk is row f: no integer division per sample
    pix_x = np.empty(W, np.int64)
    for xx in range(W):
        pix_x[xx] = xx // k
    for yy in range(Hs):
        row = (yy // k) * w
        for xx in range(W):
            f = face[yy, xx]
            if f < 0:
                continue
            p = row + pix_x[xx]
            nhit[p] += 1
            t = zbuf[yy, xx]
            px = origin[0] + t * D[yy, xx, 0]
            py = origin[1] + t * D[yy, xx, 1]
            pz = origin[2] + t * D[yy, xx, 2]
            nx, ny, nz = nf[f, 0], nf[f, 1], nf[f, 2]
            cos_i = nx * sun[0] + ny * sun[1] + nz * sun[2]
            if cos_i <= 0.0:
                continue
            if do_shadow:
                qx, qy, qz = px + shadow_eps * nx, py + shadow_eps * ny, pz + shadow_eps * nz
                ou, ov = qx / spacing + c, qy / spacing + c
                wsh = _shadow_weight(st, gframe, c, ou, ov)
                if wsh == 0.0 or wsh == 1.0:
                    shadowed = wsh == 1.0
                else:  # a shadow edge passes, or off the sweep grid: cast the shadow ray
                    n_rays += 1
                    ts, _, _, _ = _trace_one(ou, ov, qz, su, sv, sw, H, cmin, cmax, bmin, bmax, BLOCK, zlo, zhi, 0.0)
                    shadowed = ts > 0
                if shadowed:
                    nshadow[p] += 1
                    continue
            # = raytrace.shade_lit_point, written out: calling it here (even inlined) measured ~10 ms slower per frame
            vx, vy, vz = origin[0] - px, origin[1] - py, origin[2] - pz
            vn = math.sqrt(vx * vx + vy * vy + vz * vz)
            vx, vy, vz = vx / vn, vy / vn, vz / vn
            cos_r = nx * vx + ny * vy + nz * vz
            cs = min(max(vx * sun[0] + vy * sun[1] + vz * sun[2], -1.0), 1.0)
            a = _bilinear1(albedo, px / spacing + c, py / spacing + c)
            value[p] += mcewen_beta_scalar(cos_i, cos_r, beta_scalar(math.acos(cs), alpha0, L_table), a, ls_weight)
    for p in range(P):
        value[p] /= k * k
    return value, nhit, nshadow, n_rays, True


@njit(cache=True)
def pinhole_box(P, origin, R_body_from_cam, K):
    """Integer pixel box (s_min, l_min, s_max, l_max) of body-frame points ``P`` (N, 3) seen by a pinhole
    camera, and False when a point is not in front of it (eqs. 1–4 without distortion)."""
    smin = lmin = np.inf
    smax = lmax = -np.inf
    for r in range(P.shape[0]):
        qx, qy, qz = P[r, 0] - origin[0], P[r, 1] - origin[1], P[r, 2] - origin[2]
        x = R_body_from_cam[0, 0] * qx + R_body_from_cam[1, 0] * qy + R_body_from_cam[2, 0] * qz
        y = R_body_from_cam[0, 1] * qx + R_body_from_cam[1, 1] * qy + R_body_from_cam[2, 1] * qz
        z = R_body_from_cam[0, 2] * qx + R_body_from_cam[1, 2] * qy + R_body_from_cam[2, 2] * qz
        if not z > 0.0:
            return 0, 0, 0, 0, False
        s = (K[0, 0] * x + K[0, 1] * y) / z + K[0, 2]
        l = (K[1, 0] * x + K[1, 1] * y) / z + K[1, 2]
        smin, smax = min(smin, s), max(smax, s)
        lmin, lmax = min(lmin, l), max(lmax, l)
    if not (abs(smin) < 1e15 and abs(smax) < 1e15 and abs(lmin) < 1e15 and abs(lmax) < 1e15):
        return 0, 0, 0, 0, False
    return int(math.floor(smin)), int(math.floor(lmin)), int(math.ceil(smax)), int(math.ceil(lmax)), True
