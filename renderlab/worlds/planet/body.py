"""The planet world's body: a Mitsuba/Cycles sphere, a fine ellipsoid mesh, or the EV5 shape, and the ellipsoid its
limb truth is computed from.

* Equal semi-axes: the renderer's analytic sphere (exact limb).
* A spheroid or triaxial ellipsoid: an icosphere of ``mesh_level`` mapped onto the ellipsoid
  (``p = diag(a, b, c)·u``) with the ellipsoid's exact normals at the vertices (smooth shading). An inscribed
  polyhedron's outline lies inside the surface (its edges' chords dip below it); the vertices are pushed out by the
  mean dip over the edges, so the rendered limb ripples about the true one by about ``±R·Δ²/16`` (Δ the edge angle;
  :func:`mesh_limb_ripple`: ±6.7e-6 R at level 7) instead of lying inside it.
* ``ev5``: the ``ev5`` world's procedural global shape (Busch et al. 2011) for ``ev5_seed`` and ``ev5_facet_m``, with its
  relative albedo; its limb is not a conic, and its truth is that of the *equivalent ellipsoid* (same volume, centre
  and second moments of volume, uniform density), the body model an onboard system would carry.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from renderlab.errors import UserError
from renderlab.photometry import make_law
from renderlab.render.scene import BodySpec

BODY_ID = 0


@dataclass(frozen=True)
class PlanetBody:
    """The rendered body and the ellipsoid of its truth.

    Attributes
    ----------
    spec : BodySpec
        What the renderer draws (render frame).
    semi_axes_m : (3,) ndarray
        The truth ellipsoid's semi-axes, m.
    R_render_from_principal : (3, 3) ndarray
        Its principal axes in the render frame (columns).
    centre_m : (3,) ndarray
        Its centre in the render frame, m.
    limb_model : str
        ``ellipsoid`` (the rendered body is the ellipsoid) or ``equivalent_ellipsoid`` (a mesh of another shape).
    """

    spec: BodySpec
    semi_axes_m: np.ndarray
    R_render_from_principal: np.ndarray
    centre_m: np.ndarray
    limb_model: str

    @property
    def max_radius_m(self) -> float:
        """Largest distance of the rendered surface from the centre, m."""
        if self.spec.vertices is None:
            return float(np.max(self.semi_axes_m))
        v = self.spec.vertices @ self.spec.R_render_from_body.T + self.spec.center_m - self.centre_m
        return float(np.linalg.norm(v, axis=1).max())


def _edges(faces: np.ndarray, n_vertices: int) -> np.ndarray:
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]).astype(np.int64)
    key = np.unique(e.min(axis=1) * n_vertices + e.max(axis=1))
    return np.column_stack([key // n_vertices, key % n_vertices])


@functools.lru_cache(maxsize=4)
def mesh_limb_ripple(level: int) -> tuple[float, float]:
    """(outward scale of the vertices, ripple of the limb as a fraction of the radius) of an icosphere of ``level``:
    the scale makes the mean distance of the edges' points from the centre 1."""
    from renderlab.worlds.ev5.shape import icosphere

    u, f = icosphere(level)
    e = _edges(f, len(u))
    t = np.linspace(0.0, 1.0, 5)[None, :, None]
    r = np.linalg.norm(u[e[:, 0]][:, None, :] * (1 - t) + u[e[:, 1]][:, None, :] * t, axis=2)
    scale = 1.0 / float(r.mean())
    return scale, float((scale * r).max() - (scale * r).min()) / 2.0


def ellipsoid_mesh(semi_axes, level: int) -> dict:
    """BodySpec fields of the ellipsoid ``semi_axes`` as an icosphere mesh with exact vertex normals."""
    from renderlab.worlds.ev5.shape import icosphere

    axes = np.asarray(semi_axes, float)
    u, faces = icosphere(level)
    scale, _ = mesh_limb_ripple(level)
    p = u * axes
    n = p / axes**2
    return {"shape": "trimesh", "vertices": p * scale, "faces": faces,
            "vertex_normals": n / np.linalg.norm(n, axis=1, keepdims=True), "face_normals": False}


def volume_moments(vertices: np.ndarray, faces: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """(volume, centroid (3,), second moment about the centroid ∫(x−c)(x−c)ᵀ dV (3, 3)) of a closed mesh.

    Sum over the tetrahedra (0, v₁, v₂, v₃) of each facet: ``V = det/6``, ``∫x dV = V(v₁+v₂+v₃)/4``,
    ``∫xxᵀ dV = V/20 (Σ vᵢvᵢᵀ + (Σvᵢ)(Σvᵢ)ᵀ)``.
    """
    v = np.asarray(vertices, float)[np.asarray(faces)]
    vol = np.einsum("ij,ij->i", v[:, 0], np.cross(v[:, 1], v[:, 2])) / 6.0
    s = v.sum(axis=1)
    V = float(vol.sum())
    c = (vol[:, None] * s).sum(0) / 4.0 / V
    J = (vol[:, None, None] * (np.einsum("fki,fkj->fij", v, v) + np.einsum("fi,fj->fij", s, s))).sum(0) / 20.0
    return V, c, J - V * np.outer(c, c)


def equivalent_ellipsoid(vertices, faces) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(semi-axes, principal axes (columns), centre) of the uniform ellipsoid with the mesh's volume moments
    (a solid ellipsoid has ∫x² dV = V a²/5 along each principal axis)."""
    V, c, J = volume_moments(vertices, faces)
    lam, vec = np.linalg.eigh(J)
    axes = np.sqrt(5.0 * lam / V)
    if np.linalg.det(vec) < 0:
        vec[:, 0] = -vec[:, 0]
    return axes, vec, c


def _ev5_shape(world):
    from renderlab.worlds.ev5 import stream
    from renderlab.worlds.ev5.config import EV5World
    from renderlab.worlds.ev5.shape import procedural_shape

    return procedural_shape(EV5World(seed=world.ev5_seed, facet_m=world.ev5_facet_m), stream(world.ev5_seed, "shape"))


def build_body(world) -> PlanetBody:
    """The :class:`PlanetBody` of a validated :class:`~renderlab.worlds.planet.config.PlanetWorld`."""
    axes, law_name, albedo = world.resolved()
    try:
        law = make_law(law_name, **world.law_params)
    except UserError as err:
        raise UserError(f"world.law_params: {err}") from None
    R = Rotation.from_euler("xyz", world.rotation_deg, degrees=True).as_matrix()
    common = {"name": world.preset, "body_id": BODY_ID, "center_m": np.zeros(3), "R_render_from_body": R,
              "law": law, "albedo": albedo}
    if axes is None:  # ev5
        shape = _ev5_shape(world)
        spec = BodySpec(shape="trimesh", vertices=shape.vertices, faces=shape.faces,
                        vertex_albedo=shape.vertex_albedo, **common)
        ax, P, c = equivalent_ellipsoid(shape.vertices, shape.faces)
        return PlanetBody(spec, ax, R @ P, R @ c, "equivalent_ellipsoid")
    axes = np.asarray(axes, float)
    if np.ptp(axes) == 0.0:
        spec = BodySpec(shape="sphere", radius_m=float(axes[0]), **common)
    else:
        spec = BodySpec(**ellipsoid_mesh(axes, world.mesh_level), **common)
    return PlanetBody(spec, axes, R, np.zeros(3), "ellipsoid")
