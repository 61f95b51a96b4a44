"""A float64 ray-casting oracle for direct sunlight: the referee where the two renderers disagree.

Independent of both renderers (numpy only, no Mitsuba, no bpy): the scene's exact geometry in float64
(trimesh, box and plane bodies as their triangles, spheres analytic), primary rays through a k × k
stratified grid inside each pixel (:meth:`CameraModel.unproject`), the first hit by Möller–Trumbore
(Möller & Trumbore 1997) or the sphere quadric, a shadow ray from the *exact* hit point toward the sun
(no origin offset: only the hit primitive itself is excluded, and hits closer than 1e-9 m), and the
radiance ``E · r(mu0, mu, g; A)`` of the numpy photometric law (:mod:`renderlab.photometry`, the
reference the OSL shaders and Mitsuba BSDFs are tested against) with the per-vertex albedo
interpolated barycentrically. The pixel value is the mean over its k² sub-samples — the box-filtered
radiance both renderers estimate with ``spp`` samples.

Each pixel costs two scans of all triangle bounding spheres (to pick the few near its camera ray and
its shadow ray); meant for the tens to hundreds of pixels where the renderers disagree, not whole
images. Unsupported (returns ``None`` from :func:`oracle_scene`): albedo maps and mesh files.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

SHADOW_T_MIN_M = 1e-9


@dataclass
class OracleScene:
    """Float64 geometry of a scene: triangles (with per-vertex albedo factor) and analytic spheres."""

    tri: np.ndarray  # (n, 3, 3) vertices, render frame
    tri_normal: np.ndarray  # (n, 3) unit face normals (the renderers shade trimeshes flat)
    tri_albedo: np.ndarray  # (n, 3) albedo factor at the vertices (× body albedo)
    tri_body: np.ndarray  # (n,) index into ``bodies``
    centre: np.ndarray  # (n, 3) bounding-sphere centres
    radius: np.ndarray  # (n,) bounding-sphere radii
    spheres: list  # (centre (3,), radius, body index)
    bodies: list  # BodySpec per index


@dataclass
class PixelTruth:
    """Oracle values of pixels: box-filtered radiance, its value without cast shadows, the lit
    fraction, the standard deviation of the per-sample radiance inside the pixel and the largest
    unshadowed sample radiance (what one renderer sample can contribute at most)."""

    radiance: np.ndarray
    unshadowed: np.ndarray
    lit_fraction: np.ndarray
    sample_std: np.ndarray
    sample_max: np.ndarray


def _box_triangles():
    V = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return V, np.array([(a, b, c) for a, b, c, d in quads] + [(a, c, d) for a, b, c, d in quads])


def oracle_scene(scene) -> OracleScene | None:
    """Float64 geometry of a :class:`SceneDescription` (None if a body is not supported)."""
    tris, alb, bid, spheres = [], [], [], []
    for k, b in enumerate(scene.bodies):
        if b.albedo_map is not None or b.shape == "mesh":
            return None
        R, c = np.asarray(b.R_render_from_body, float), np.asarray(b.center_m, float)
        if b.shape == "sphere":
            spheres.append((c, float(b.radius_m), k))
            continue
        if b.shape == "trimesh":
            V, F = np.asarray(b.vertices, float), np.asarray(b.faces, np.int64)
            va = np.ones(len(V)) if b.vertex_albedo is None else np.asarray(b.vertex_albedo, float)
        elif b.shape == "box":
            V, F = _box_triangles()
            V = V * np.asarray(b.size_m, float)
            va = np.ones(len(V))
        elif b.shape == "plane":
            sx, sy = b.size_m
            V = np.array([[-sx / 2, -sy / 2, 0.0], [sx / 2, -sy / 2, 0.0], [sx / 2, sy / 2, 0.0], [-sx / 2, sy / 2, 0.0]])
            F, va = np.array([[0, 1, 2], [0, 2, 3]]), np.ones(4)
        else:
            return None
        tris.append((V @ R.T + c)[F])
        alb.append(va[F])
        bid.append(np.full(len(F), k))
    T = np.concatenate(tris) if tris else np.zeros((0, 3, 3))
    n = np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    C = T.mean(axis=1)
    return OracleScene(tri=T, tri_normal=n, tri_albedo=np.concatenate(alb) if alb else np.zeros((0, 3)),
                       tri_body=np.concatenate(bid) if bid else np.zeros(0, int), centre=C,
                       radius=np.linalg.norm(T - C[:, None], axis=2).max(axis=1) if len(T) else np.zeros(0),
                       spheres=spheres, bodies=list(scene.bodies))


def _near_ray(sc: OracleScene, o, d, margin):
    """Triangles whose bounding sphere comes within ``margin`` of the half-line o + t·d (t ≥ 0)."""
    w = sc.centre - o
    t = np.maximum(w @ d, 0.0)
    return np.nonzero(np.linalg.norm(w - t[:, None] * d, axis=1) <= sc.radius + margin)[0]


def _moller_trumbore(o, d, T, t_min):
    """Rays (R, 3) × triangles (K, 3, 3) → (t, u, v), each (R, K); t = inf where missed."""
    v0, e1, e2 = T[:, 0], T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]
    p = np.cross(d[:, None, :], e2[None])
    det = np.einsum("rkj,kj->rk", p, e1)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / det
        s = o[:, None, :] - v0[None]
        u = np.einsum("rkj,rkj->rk", s, p) * inv
        q = np.cross(s, e1[None])
        v = np.einsum("rj,rkj->rk", d, q) * inv
        t = np.einsum("rkj,kj->rk", q, e2) * inv
    ok = (det != 0) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > t_min)
    return np.where(ok, t, np.inf), u, v


def _sphere_t(o, d, c, r, t_min):
    oc = o - c
    b = np.einsum("ij,ij->i", oc, d)
    disc = b * b - (np.einsum("ij,ij->i", oc, oc) - r * r)
    sq = np.sqrt(np.where(disc >= 0, disc, 0.0))
    t0, t1 = -b - sq, -b + sq
    t = np.where(t0 > t_min, t0, np.where(t1 > t_min, t1, np.inf))
    return np.where(disc >= 0, t, np.inf)


def _first_hit(sc, o, d, cand, t_min, chunk=64):
    """First hit of rays o, d among candidate triangles and all spheres: (t, primitive, u, v);
    primitive ≥ 0 is a triangle index, −1 − k sphere k, and −(len+1) nothing."""
    n = len(d)
    t_best = np.full(n, np.inf)
    prim = np.full(n, -(len(sc.spheres) + 1), dtype=np.int64)
    bu, bv = np.zeros(n), np.zeros(n)
    for a in range(0, len(cand), chunk * 64):
        c = cand[a:a + chunk * 64]
        for r0 in range(0, n, chunk):
            sl = slice(r0, r0 + chunk)
            t, u, v = _moller_trumbore(o[sl], d[sl], sc.tri[c], t_min)
            j = np.argmin(t, axis=1)
            ar = np.arange(len(j))
            tj = t[ar, j]
            better = tj < t_best[sl]
            idx = np.nonzero(better)[0] + r0
            t_best[idx], prim[idx], bu[idx], bv[idx] = tj[better], c[j[better]], u[ar, j][better], v[ar, j][better]
    for k, (cen, rad, _) in enumerate(sc.spheres):
        t = _sphere_t(o, d, cen, rad, t_min)
        better = t < t_best
        t_best[better], prim[better] = t[better], -1 - k
    return t_best, prim, bu, bv


def _occluded(sc, p, sun, own, cand, chunk=64):
    """Shadow test of points p (N, 3) toward the sun; ``own`` = each point's primitive (excluded)."""
    occ = np.zeros(len(p), bool)
    dirs = np.broadcast_to(sun, p.shape)
    for a in range(0, len(cand), chunk * 64):
        c = cand[a:a + chunk * 64]
        for r0 in range(0, len(p), chunk):
            sl = slice(r0, r0 + chunk)
            t, _, _ = _moller_trumbore(p[sl], dirs[sl], sc.tri[c], SHADOW_T_MIN_M)
            t[own[sl, None] == c[None, :]] = np.inf
            occ[sl] |= np.isfinite(t).any(axis=1)
    for k, (cen, rad, _) in enumerate(sc.spheres):
        t = _sphere_t(p, np.ascontiguousarray(dirs), cen, rad, SHADOW_T_MIN_M)
        t[own == -1 - k] = np.inf  # a convex sphere cannot shadow its own sunlit side
        occ |= np.isfinite(t)
    return occ


def pixel_truth(sc: OracleScene, spec, sl: np.ndarray, k: int = 8) -> PixelTruth:
    """Oracle radiance of pixels ``sl`` (N, 2) of frame ``spec`` (FrameSpec) with k × k sub-samples."""
    cam, pose = spec.camera, spec.pose
    R, o_cam = pose.rotation.as_matrix(), np.asarray(pose.position_m, float)
    sun = np.asarray(spec.sun.direction_render, float)
    sun = sun / np.linalg.norm(sun)
    E = float(spec.sun.irradiance_w_m2)
    sub = (np.arange(k) + 0.5) / k - 0.5
    du, dv = np.meshgrid(sub, sub)
    offs = np.column_stack([du.ravel(), dv.ravel()])
    out = {key: np.zeros(len(sl)) for key in ("L", "U", "f", "s", "m")}
    for i, (s, line) in enumerate(np.asarray(sl, float)):
        d = cam.unproject(np.column_stack([s + offs[:, 0], line + offs[:, 1]])) @ R.T
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        dc = d.mean(axis=0)
        dc /= np.linalg.norm(dc)
        spread = float(np.max(np.linalg.norm(d - dc, axis=1)))
        # candidates: triangles near the central ray, wide enough for the pixel's rays at the far end
        far = max(float(np.max(np.linalg.norm(sc.centre - o_cam, axis=1))) if len(sc.centre) else 0.0, 1.0)
        t, prim, u, v = _first_hit(sc, np.broadcast_to(o_cam, d.shape).copy(), d,
                                   _near_ray(sc, o_cam, dc, spread * far + 1e-6), 0.0)
        hit = np.isfinite(t)
        P = o_cam + np.where(hit, t, 0.0)[:, None] * d
        is_tri = hit & (prim >= 0)
        n = np.zeros_like(P)
        n[is_tri] = sc.tri_normal[prim[is_tri]]
        body = np.full(len(d), -1)
        body[is_tri] = sc.tri_body[prim[is_tri]]
        alb = np.ones(len(d))
        ta = sc.tri_albedo[prim[is_tri]]
        alb[is_tri] = (1 - u[is_tri] - v[is_tri]) * ta[:, 0] + u[is_tri] * ta[:, 1] + v[is_tri] * ta[:, 2]
        for kk, (cen, rad, b) in enumerate(sc.spheres):
            m = hit & (prim == -1 - kk)
            n[m] = (P[m] - cen) / rad
            body[m] = b
        mu0 = n @ sun
        mu = np.einsum("ij,ij->i", n, -d)
        g = np.arccos(np.clip(-d @ sun, -1.0, 1.0))
        rad_s = np.zeros(len(d))
        for b in np.unique(body[hit]):
            m = hit & (body == b) & (mu0 > 0) & (mu > 0)
            bs = sc.bodies[b]
            rad_s[m] = E * bs.law.radiance_factor(mu0[m], mu[m], g[m], float(bs.albedo) * alb[m])
        facing = rad_s > 0
        lit = facing.copy()
        if facing.any():
            pc = P[facing].mean(axis=0)
            foot = float(np.max(np.linalg.norm(P[facing] - pc, axis=1)))
            cand = _near_ray(sc, pc, sun, foot + 1e-6)
            lit[facing] = ~_occluded(sc, P[facing], sun, prim[facing], cand)
        x = np.where(lit, rad_s, 0.0)
        out["L"][i], out["U"][i], out["f"][i], out["s"][i], out["m"][i] = \
            x.mean(), rad_s.mean(), lit.mean(), x.std(), rad_s.max()
    return PixelTruth(radiance=out["L"], unshadowed=out["U"], lit_fraction=out["f"], sample_std=out["s"],
                      sample_max=out["m"])


def consistent(L: np.ndarray, truth: PixelTruth, spp: int, k: int) -> np.ndarray:
    """Whether renderer values L agree with the oracle within sampling noise:
    |L − L_oracle| ≤ 3·σ·(1/√spp + 1/k) + 2·x_max/spp + 1 % of the unshadowed value.

    σ is the std of the radiance over the pixel: the renderer's spp-sample mean and the oracle's k²
    stratified mean fluctuate by ≈σ/√spp and ≈σ/k where an edge crosses the pixel. A sliver smaller
    than 1/spp of the pixel is caught by one sample or by none, a jump of x_max/spp (x_max the largest
    unshadowed sample radiance) that the Gaussian term does not cover: two such samples are allowed.
    """
    tol = (3.0 * truth.sample_std * (1.0 / np.sqrt(spp) + 1.0 / k) + 2.0 * truth.sample_max / spp
           + 0.01 * truth.unshadowed + 1e-9)
    return np.abs(np.asarray(L, float) - truth.radiance) <= tol


def centre_ranges(sc: OracleScene, spec, sl: np.ndarray) -> np.ndarray:
    """Float64 range (m, camera centre to first hit; inf where nothing is hit) along the rays through the pixel
    centres ``sl`` (N, 2) of frame ``spec``: the exact counterpart of the renderers' range AOV."""
    R, o = spec.pose.rotation.as_matrix(), np.asarray(spec.pose.position_m, float)
    d = spec.camera.unproject(np.asarray(sl, float)) @ R.T
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    t = np.full(len(d), np.inf)
    for i in range(len(d)):
        cand = _near_ray(sc, o, d[i], 1e-6)
        t[i] = _first_hit(sc, o[None], d[i:i + 1], cand, 0.0)[0][0]
    return t
