r"""Gravitation of a constant-density closed triangle mesh: potential, attraction, gravity gradient and Laplacian.

R. A. Werner & D. J. Scheeres, "Exterior gravitation of a polyhedron derived and compared with harmonic and mascon
gravitation representations of asteroid 4769 Castalia", Celestial Mechanics and Dynamical Astronomy 65, 313–344
(1997), doi:10.1007/BF00053511 (WS97). With Gσ = G·ρ (density ρ), for a field point P (the equation labels P1–P7
are this module's; WS97 number the same expressions in their own sequence):

.. math::

    U &= \tfrac12 G\sigma \sum_{e} \mathbf r_e\cdot\mathbf E_e\cdot\mathbf r_e\,L_e
         - \tfrac12 G\sigma \sum_{f} \mathbf r_f\cdot\mathbf F_f\cdot\mathbf r_f\,\omega_f            &\quad (P1)\\
    \nabla U &= -G\sigma \sum_{e} \mathbf E_e\cdot\mathbf r_e\,L_e
                + G\sigma \sum_{f} \mathbf F_f\cdot\mathbf r_f\,\omega_f                              &\quad (P2)\\
    \nabla\nabla U &= G\sigma \sum_{e} \mathbf E_e\,L_e - G\sigma \sum_{f} \mathbf F_f\,\omega_f     &\quad (P3)\\
    \nabla^2 U &= -G\sigma \sum_{f} \omega_f                                                          &\quad (P4)

(WS97's potential, attraction, gradient-matrix and Laplacian expressions; U > 0, the attraction is +∇U). The sums
run over the edges e and the faces f of the mesh:

* face dyad :math:`\mathbf F_f = \hat{\mathbf n}_f\hat{\mathbf n}_f` (outward unit normal), edge dyad
  :math:`\mathbf E_e = \hat{\mathbf n}_A\hat{\mathbf n}^A_{12} + \hat{\mathbf n}_B\hat{\mathbf n}^B_{21}` (P5), with
  A, B the two faces meeting at the edge and :math:`\hat{\mathbf n}^A_{12}` the unit normal of the edge in the plane
  of face A pointing out of A (:math:`(\mathbf P_2 - \mathbf P_1)/e \times \hat{\mathbf n}_A` for the edge P1 → P2
  as A's counter-clockwise boundary traverses it); both computed once per mesh;
* :math:`\mathbf r_e`, :math:`\mathbf r_f`: from P to any point of the edge / face (a vertex);
* per-edge factor :math:`L_e = \ln\frac{a + b + e}{a + b - e}` (P6), a, b the distances from P to the edge's ends,
  e its length;
* face solid angle seen from P, with :math:`\mathbf r_i` from P to the face's vertices in counter-clockwise order
  (Van Oosterom & Strackee 1983, doi:10.1109/TBME.1983.325207, the form WS97 use):

.. math::

    \omega_f = 2\arctan\frac{\mathbf r_1\cdot(\mathbf r_2\times\mathbf r_3)}
        {r_1 r_2 r_3 + r_1(\mathbf r_2\cdot\mathbf r_3) + r_2(\mathbf r_3\cdot\mathbf r_1)
         + r_3(\mathbf r_1\cdot\mathbf r_2)}   \quad (P7)

  (two-argument arctangent). :math:`\sum_f\omega_f` is 0 outside the body and 4π inside, so (P4) is 0 outside and
  −4πGρ inside (WS97's test of whether a point is inside).

The expressions hold outside and inside the body; on an edge (L_e) or in a face plane at the face (ω_f) they are
singular. Everything is vectorised numpy, evaluated over chunks of field points (a loop over points would be the
only natural numba kernel; not needed at the descent's evaluation counts). The mass is ρ·V with V the mesh volume
(divergence theorem), the centre of mass that of the uniform solid (signed tetrahedra from the origin).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from renderlab.errors import UserError

#: CODATA 2018 Newtonian constant of gravitation, m³ kg⁻¹ s⁻²
G_SI = 6.67430e-11


@dataclass(frozen=True)
class GravityField:
    """Potential (m²/s²), attraction (m/s²), gravity gradient (1/s²) and Laplacian (1/s²) at N field points."""

    potential: np.ndarray      # (N,)
    acceleration: np.ndarray   # (N, 3)
    gradient: np.ndarray       # (N, 3, 3)
    laplacian: np.ndarray      # (N,)


def _edges(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unique edges of a closed, consistently oriented mesh: (vertex pair (E, 2) as face A traverses it, face A,
    face B) — each undirected edge appears once as i → j in face A and once as j → i in face B."""
    nf = len(faces)
    i = faces.reshape(-1)
    j = np.roll(faces, -1, axis=1).reshape(-1)
    f = np.repeat(np.arange(nf), 3)
    nv = int(faces.max()) + 1
    fwd = i < j
    key = np.minimum(i, j).astype(np.int64) * nv + np.maximum(i, j)
    order = np.lexsort((~fwd, key))
    key, i, j, f, fwd = key[order], i[order], j[order], f[order], fwd[order]
    if len(key) % 2 or np.any(key[0::2] != key[1::2]) or (len(key) > 2 and np.any(key[2::2] == key[1:-1:2])):
        raise UserError("polyhedron gravity: the mesh is not closed (every edge must be shared by exactly two faces)")
    if not np.all(fwd[0::2] & ~fwd[1::2]):
        raise UserError("polyhedron gravity: the faces are not consistently oriented (an edge runs the same way "
                        "in both of its faces)")
    return np.column_stack([i[0::2], j[0::2]]), f[0::2], f[1::2]


class PolyhedronGravity:
    """The field of a constant-density closed triangle mesh (module docstring, eqs. P1–P7).

    Parameters
    ----------
    vertices : array (V, 3)
        Vertex positions, m (body frame).
    faces : array (F, 3) of int
        Triangles; counter-clockwise seen from outside (an inward-wound mesh, negative volume, is flipped).
    density_kg_m3 : float, optional
        Bulk density ρ.
    gm_m3_s2 : float, optional
        Total GM instead of the density (then Gρ = GM / V). Give exactly one of the two.
    G : float
        Gravitational constant (default CODATA 2018).
    chunk : int
        Field points × edges evaluated per numpy pass (memory bound).
    """

    def __init__(self, vertices, faces, *, density_kg_m3: float | None = None, gm_m3_s2: float | None = None,
                 G: float = G_SI, chunk: int = 50_000):
        v = np.asarray(vertices, float)
        f = np.asarray(faces, np.int64)
        if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3 or len(f) < 4 or not np.all(np.isfinite(v)):
            raise UserError("polyhedron gravity: give vertices (V, 3) and triangle faces (F >= 4, 3)")
        if f.min() < 0 or f.max() >= len(v):
            raise UserError("polyhedron gravity: a face refers to a vertex that does not exist")
        tri = v[f]
        six_vol = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2]))
        if six_vol.sum() < 0:
            f = f[:, ::-1].copy()
            tri = v[f]
            six_vol = -six_vol
        self.vertices, self.faces = v, f
        self.volume_m3 = float(six_vol.sum() / 6.0)
        if not self.volume_m3 > 0:
            raise UserError("polyhedron gravity: the mesh encloses no volume")
        self.centroid_m = (six_vol[:, None] * tri.sum(1)).sum(0) / (4.0 * six_vol.sum())
        if (density_kg_m3 is None) == (gm_m3_s2 is None):
            raise UserError("polyhedron gravity: give exactly one of density_kg_m3 and gm_m3_s2")
        g_rho = G * float(density_kg_m3) if gm_m3_s2 is None else float(gm_m3_s2) / self.volume_m3
        if not (math.isfinite(g_rho) and g_rho >= 0):
            raise UserError("polyhedron gravity: density / GM must be finite and non-negative")
        self.g_rho, self.G, self.chunk = g_rho, float(G), int(chunk)
        self._precompute(tri)

    def _precompute(self, tri: np.ndarray) -> None:
        """Face normals and dyads F_f, unique edges and their dyads E_e (eq. P5)."""
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        area2 = np.linalg.norm(n, axis=1)
        if np.any(area2 <= 0):
            raise UserError("polyhedron gravity: the mesh has a face of zero area")
        n /= area2[:, None]
        self.face_normals = n
        self.F = n[:, :, None] * n[:, None, :]                       # (F, 3, 3)
        pair, fa, fb = _edges(self.faces)
        p1, p2 = self.vertices[pair[:, 0]], self.vertices[pair[:, 1]]
        d = p2 - p1
        length = np.linalg.norm(d, axis=1)
        d /= length[:, None]
        n12a = np.cross(d, n[fa])          # out of face A, in its plane (A traverses P1 → P2)
        n21b = np.cross(-d, n[fb])         # out of face B (B traverses P2 → P1)
        self.E = n[fa][:, :, None] * n12a[:, None, :] + n[fb][:, :, None] * n21b[:, None, :]   # (E, 3, 3)
        self.edge_vertices, self.edge_length = pair, length

    # ------------------------------------------------------------------ mass properties
    @property
    def gm_m3_s2(self) -> float:
        """GM = Gρ V, m³/s²."""
        return self.g_rho * self.volume_m3

    @property
    def mass_kg(self) -> float:
        return self.gm_m3_s2 / self.G

    # ------------------------------------------------------------------ the field
    def field(self, points) -> GravityField:
        """U, ∇U, ∇∇U and ∇²U (eqs. P1–P4) at ``points`` (N, 3) or (3,), m."""
        p = np.atleast_2d(np.asarray(points, float))
        if p.ndim != 2 or p.shape[1] != 3:
            raise UserError("polyhedron gravity: field points must be (N, 3)")
        n = len(p)
        out = GravityField(np.empty(n), np.empty((n, 3)), np.empty((n, 3, 3)), np.empty(n))
        step = max(1, self.chunk // max(len(self.E), len(self.F)))
        for s in range(0, n, step):
            self._field_chunk(p[s:s + step], out, s)
        return out

    def _field_chunk(self, p: np.ndarray, out: GravityField, s: int) -> None:
        rv = self.vertices[None] - p[:, None]                                   # (n, V, 3): P → every vertex
        dv = np.sqrt(np.einsum("nvi,nvi->nv", rv, rv))                          # (n, V)
        # edges: r_e from P to the edge's first vertex, L_e of eq. P6
        e0, e1 = self.edge_vertices[:, 0], self.edge_vertices[:, 1]
        ab = dv[:, e0] + dv[:, e1]
        L = np.log((ab + self.edge_length) / (ab - self.edge_length))          # (n, E)
        ra = rv[:, e0]                                                           # (n, E, 3)
        Er = np.einsum("eij,nej->nei", self.E, ra)                               # E_e · r_e
        # faces: r_i from P to the vertices, ω_f of eq. P7
        f0, f1, f2 = self.faces[:, 0], self.faces[:, 1], self.faces[:, 2]
        r1, r2, r3 = rv[:, f0], rv[:, f1], rv[:, f2]                             # (n, F, 3)
        l1, l2, l3 = dv[:, f0], dv[:, f1], dv[:, f2]
        cx = r2[..., 1] * r3[..., 2] - r2[..., 2] * r3[..., 1]
        cy = r2[..., 2] * r3[..., 0] - r2[..., 0] * r3[..., 2]
        cz = r2[..., 0] * r3[..., 1] - r2[..., 1] * r3[..., 0]
        num = r1[..., 0] * cx + r1[..., 1] * cy + r1[..., 2] * cz
        den = l1 * l2 * l3 + l1 * np.einsum("nfi,nfi->nf", r2, r3) + l2 * np.einsum("nfi,nfi->nf", r3, r1) \
            + l3 * np.einsum("nfi,nfi->nf", r1, r2)
        w = 2.0 * np.arctan2(num, den)                                           # (n, F)
        # F_f · r_f = n_f (n_f · r_1): the face's plane distance along its normal
        h = np.einsum("fi,nfi->nf", self.face_normals, r1)                       # (n, F)
        k = slice(s, s + len(p))
        gs = self.g_rho
        wh = w * h
        out.potential[k] = 0.5 * gs * (np.einsum("nei,nei->n", ra, Er * L[..., None]) - np.einsum("nf,nf->n", wh, h))
        out.acceleration[k] = gs * (wh @ self.face_normals - np.einsum("ne,nei->ni", L, Er))
        out.gradient[k] = gs * (L @ self.E.reshape(-1, 9) - w @ self.F.reshape(-1, 9)).reshape(-1, 3, 3)
        out.laplacian[k] = -gs * w.sum(1)

    def at(self, r) -> tuple[float, np.ndarray]:
        """(U, ∇U) at one point ``r`` (3,): eqs. P1, P2 by the compiled loop over edges and faces
        (:func:`_point_kernel`), the integrator's path (equal to :meth:`field` to rounding)."""
        p = np.asarray(r, float).reshape(3)
        u, a = _point_kernel(p, self.vertices, self.edge_vertices, self.edge_length, self.E, self.faces,
                             self.face_normals)
        return self.g_rho * u, self.g_rho * a

    def potential(self, r) -> np.ndarray:
        """U (eq. P1) at ``r`` (..., 3), m²/s² (positive)."""
        r = np.asarray(r, float)
        return self.field(r.reshape(-1, 3)).potential.reshape(r.shape[:-1])

    def acceleration(self, r) -> np.ndarray:
        """Attraction ∇U (eq. P2) at ``r`` (..., 3), m/s²."""
        r = np.asarray(r, float)
        return self.field(r.reshape(-1, 3)).acceleration.reshape(r.shape)


@numba.njit(cache=True)
def _point_kernel(p, verts, edges, elen, E, faces, normals):  # pragma: no cover - compiled
    """Σ_e r_e·E_e·r_e L_e / 2 − Σ_f (n_f·r_f)² ω_f / 2 and −Σ_e E_e r_e L_e + Σ_f n_f (n_f·r_f) ω_f at ``p``
    (eqs. P1, P2 without the factor Gρ)."""
    nv = verts.shape[0]
    rv = np.empty((nv, 3))
    dv = np.empty(nv)
    for i in range(nv):
        x, y, z = verts[i, 0] - p[0], verts[i, 1] - p[1], verts[i, 2] - p[2]
        rv[i, 0], rv[i, 1], rv[i, 2] = x, y, z
        dv[i] = np.sqrt(x * x + y * y + z * z)
    u = 0.0
    a = np.zeros(3)
    for e in range(edges.shape[0]):
        i, j = edges[e, 0], edges[e, 1]
        ab = dv[i] + dv[j]
        le = np.log((ab + elen[e]) / (ab - elen[e]))
        for m in range(3):
            er = E[e, m, 0] * rv[i, 0] + E[e, m, 1] * rv[i, 1] + E[e, m, 2] * rv[i, 2]
            u += 0.5 * rv[i, m] * er * le
            a[m] -= er * le
    for f in range(faces.shape[0]):
        i, j, k = faces[f, 0], faces[f, 1], faces[f, 2]
        x1, y1, z1 = rv[i, 0], rv[i, 1], rv[i, 2]
        x2, y2, z2 = rv[j, 0], rv[j, 1], rv[j, 2]
        x3, y3, z3 = rv[k, 0], rv[k, 1], rv[k, 2]
        num = x1 * (y2 * z3 - z2 * y3) + y1 * (z2 * x3 - x2 * z3) + z1 * (x2 * y3 - y2 * x3)
        den = dv[i] * dv[j] * dv[k] + dv[i] * (x2 * x3 + y2 * y3 + z2 * z3) \
            + dv[j] * (x3 * x1 + y3 * y1 + z3 * z1) + dv[k] * (x1 * x2 + y1 * y2 + z1 * z2)
        w = 2.0 * np.arctan2(num, den)
        h = normals[f, 0] * x1 + normals[f, 1] * y1 + normals[f, 2] * z1
        u -= 0.5 * h * h * w
        for m in range(3):
            a[m] += normals[f, m] * h * w
    return u, a
