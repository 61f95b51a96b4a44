"""Plain-numpy reference ray caster for maplets: every ray against every facet (Möller–Trumbore).

No acceleration structure and no numba, so it shares no code with the kernels of :mod:`.raytrace`: the tests
use it as the oracle of :func:`~.raytrace.trace_rays` and the shading kernels, and the speed benchmark as the
plain-numpy baseline (Retina synthetic image steps 3–4, single bounce with shadow rays).
"""

from __future__ import annotations

import numpy as np


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
