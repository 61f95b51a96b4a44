"""Global shape of 2008 EV5: procedural (consistent with the radar shape) or a user's shape model.

Procedural body (Busch et al. 2011, Icarus 212, 649: 420 × 410 × 390 m ± 10 %, oblate, an
equatorial ridge, a ~150 m concavity). The surface is a star-shaped radius function of the
direction u:

    r(u) = r_ell(u) + h_ridge · exp(−(lat/w)²) − d_cav · (1 − (θ/θ_c)²)²₊ + Σ_k a_k cos(2π k_k·u R + φ_k)

+ Σ_j craters_j(θ_j) with r_ell the ellipsoid of semi-axes (a − h_ridge, b − h_ridge, c), θ the angle from the
concavity centre (θ_c = D_cav / 2 / R), and random plane waves with a power-law spectrum
(amplitude ∝ λ^0.8, λ from 200 m down to 5 facets) scaled to ``roughness_rms_m``, and
``global_craters`` simple bowls (depth 0.2 D, rim 0.04 D, N(>D) ∝ D^−2, D from 5 facets to 80 m). Vertices of a
subdivided icosahedron (level chosen so the mean edge ≤ ``facet_m``) are pushed to r(u)·u.
Seeded: the same ``world.seed`` makes the same arrays.

A user's model replaces it: OBJ, PLY (ASCII or binary), STL or GLB through the lab's one mesh reader
(:mod:`renderlab.render.mesh_io`: polygons triangulated, degenerate faces removed), or Gaskell ICQ (q, then
6 faces of (q+1)² vertices, km; read here). Units per ``shape_file_units``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from renderlab.errors import UserError


@dataclass
class GlobalShape:
    """A closed triangle mesh in the body frame (m) with per-vertex relative albedo.

    ``radius_fn`` is the procedural radius function r(u) (None for a user's mesh).
    """

    vertices: np.ndarray  # (V, 3) float64, m
    faces: np.ndarray  # (F, 3) int32, counter-clockwise seen from outside
    vertex_albedo: np.ndarray  # (V,) float32, mean ≈ 1
    radius_fn: object | None = None

    def extents(self) -> np.ndarray:
        return self.vertices.max(0) - self.vertices.min(0)

    def volume(self) -> float:
        """Enclosed volume (divergence theorem over the facets), m³."""
        v = self.vertices[self.faces]
        return float(np.einsum("ij,ij->i", v[:, 0], np.cross(v[:, 1], v[:, 2])).sum() / 6.0)

    def equivalent_diameter(self) -> float:
        return float((6.0 * self.volume() / math.pi) ** (1.0 / 3.0))


# ------------------------------------------------------------------------------- icosphere
def icosphere(level: int) -> tuple[np.ndarray, np.ndarray]:
    """Unit icosphere: vertices (V, 3) and faces (20·4^level, 3), outward counter-clockwise."""
    t = (1.0 + 5 ** 0.5) / 2.0
    v = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
                  [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], float)
    f = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
                  [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
                  [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]], np.int64)
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    for _ in range(level):
        nv = len(v)
        e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
        key = np.minimum(e[:, 0], e[:, 1]) * nv + np.maximum(e[:, 0], e[:, 1])
        uniq, inv = np.unique(key, return_inverse=True)
        a, b = uniq // nv, uniq % nv
        mid = v[a] + v[b]
        mid /= np.linalg.norm(mid, axis=1, keepdims=True)
        m = (inv + nv).reshape(3, -1)  # midpoints of edges 01, 12, 20 of every face
        v = np.concatenate([v, mid])
        f = np.concatenate([np.column_stack([f[:, 0], m[0], m[2]]), np.column_stack([f[:, 1], m[1], m[0]]),
                            np.column_stack([f[:, 2], m[2], m[1]]), np.column_stack([m[0], m[1], m[2]])])
    return v, f.astype(np.int32)


def level_for_facet(radius_m: float, facet_m: float) -> int:
    """Smallest icosphere level whose mean equilateral edge on a sphere of ``radius_m`` ≤ ``facet_m``."""
    for level in range(0, 12):
        area = 4 * math.pi * radius_m ** 2 / (20 * 4 ** level)
        if math.sqrt(4 * area / math.sqrt(3)) <= facet_m:
            return level
    raise UserError(f"world.facet_m {facet_m} m is too fine for a {radius_m:.0f} m body (more than 20·4^11 facets)")


# ------------------------------------------------------------------------------- procedural EV5
class RadiusFunction:
    """r(u) of the procedural body (see module docstring); call with unit vectors (N, 3)."""

    def __init__(self, world, rng: np.random.Generator):
        a, b, c = (np.asarray(world.size_m, float) / 2.0)
        self.h_ridge = float(world.ridge_height_m)
        self.axes = np.array([a - self.h_ridge, b - self.h_ridge, c])
        self.R = float(np.cbrt(a * b * c))
        lat, lon = math.radians(world.concavity_lat_deg), math.radians(world.concavity_lon_deg)
        self.u_cav = np.array([math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)])
        self.theta_cav = world.concavity_diameter_m / 2.0 / self.R
        self.d_cav = float(world.concavity_depth_m)
        n_wave = 96
        lam = np.exp(rng.uniform(np.log(max(5 * world.facet_m, 2.0)), np.log(200.0), n_wave))
        dirs = rng.normal(size=(n_wave, 3))
        dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
        self.k = dirs / lam[:, None] * (2 * math.pi)
        self.phi = rng.uniform(0, 2 * math.pi, n_wave)
        amp = lam ** 0.8
        self.amp = amp * (world.roughness_rms_m / math.sqrt(0.5 * np.sum(amp ** 2)))
        # craters: N(>D) ∝ D^-2 between 5 facets and 80 m, simple-bowl profile in angle
        d_min = max(5 * world.facet_m, 4.0)
        n_cr = int(world.global_craters) if d_min < 80 else 0
        u_cr = rng.random(n_cr)
        self.cr_d = (d_min ** -2 - u_cr * (d_min ** -2 - 80.0 ** -2)) ** -0.5
        c = rng.normal(size=(n_cr, 3))
        self.cr_c = c / np.linalg.norm(c, axis=1, keepdims=True)

    def __call__(self, u: np.ndarray) -> np.ndarray:
        u = np.asarray(u, float)
        r = 1.0 / np.sqrt(((u / self.axes) ** 2).sum(-1))
        lat = np.arcsin(np.clip(u[..., 2], -1, 1))
        r = r + self.h_ridge * np.exp(-(lat / math.radians(12.0)) ** 2)
        if self.theta_cav > 0:
            th = np.arccos(np.clip(u @ self.u_cav, -1, 1))
            r = r - self.d_cav * np.clip(1 - (th / self.theta_cav) ** 2, 0, None) ** 2
        out = np.empty(u.shape[:-1])
        flat_u, flat_r, flat_o = u.reshape(-1, 3), r.reshape(-1), out.reshape(-1)
        alpha = self.cr_d / 2 / self.R  # angular radii of the craters
        for s in range(0, len(flat_u), 32768):  # chunks keep the (N, waves) temporaries small
            p = flat_u[s:s + 32768] * self.R
            flat_o[s:s + 32768] = flat_r[s:s + 32768] + np.cos(p @ self.k.T + self.phi) @ self.amp
            if len(alpha):
                x = np.arccos(np.clip(flat_u[s:s + 32768] @ self.cr_c.T, -1, 1)) / alpha  # r / R per crater
                with np.errstate(divide="ignore"):
                    rim_part = np.where(x < 1.5, (1 / np.maximum(x, 1)) ** 3 * (1 - ((x - 1) / 0.5) ** 2) ** 2, 0.0)
                prof = np.where(x < 1, 0.2 * (x * x - 1) + 0.04, 0.04 * rim_part)
                flat_o[s:s + 32768] += prof @ self.cr_d
        return out

    def surface_point(self, u: np.ndarray) -> np.ndarray:
        u = np.asarray(u, float) / np.linalg.norm(u, axis=-1, keepdims=True)
        return u * self(u)[..., None]


def _albedo_field(points: np.ndarray, rms: float, rng: np.random.Generator, scale_m: float) -> np.ndarray:
    """Relative albedo 1 + correlated noise (random plane waves, wavelengths ≥ scale_m), rms ``rms``."""
    n = 48
    lam = np.exp(rng.uniform(np.log(scale_m), np.log(100 * scale_m), n))
    d = rng.normal(size=(n, 3))
    k = d / np.linalg.norm(d, axis=1, keepdims=True) / lam[:, None] * (2 * math.pi)
    phi = rng.uniform(0, 2 * math.pi, n)
    out = np.empty(len(points), np.float32)
    for s in range(0, len(points), 32768):
        out[s:s + 32768] = np.cos(points[s:s + 32768] @ k.T + phi).sum(1)
    return (1.0 + rms * out / math.sqrt(n / 2)).clip(0.2, None).astype(np.float32)


def procedural_shape(world, rng: np.random.Generator) -> GlobalShape:
    """The procedural EV5 mesh (module docstring) with ~``world.facet_m`` facets."""
    radius = RadiusFunction(world, rng)
    u, faces = icosphere(level_for_facet(radius.R, world.facet_m))
    vertices = radius.surface_point(u)
    albedo = _albedo_field(vertices, world.albedo_rms, rng, scale_m=max(5.0, 3 * world.facet_m))
    return GlobalShape(vertices, faces, albedo, radius)


# ------------------------------------------------------------------------------- user models
def _read_icq(path: Path):
    """Gaskell ICQ: q, then 6 faces × (q+1)² vertices (x y z, km), index (i, j, face) with i fastest."""
    tok = path.read_text().split()
    q = int(tok[0])
    n = q + 1
    xyz = np.array(tok[1:1 + 6 * n * n * 3], float).reshape(6, n, n, 3)  # [face, j, i]
    if xyz.size != 6 * n * n * 3:
        raise ValueError("truncated ICQ file")
    idx = np.arange(6 * n * n).reshape(6, n, n)
    a, b, c, d = idx[:, :-1, :-1], idx[:, :-1, 1:], idx[:, 1:, :-1], idx[:, 1:, 1:]
    faces = np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3), np.stack([a, d, c], -1).reshape(-1, 3)])
    verts = xyz.reshape(-1, 3)
    # merge the duplicated vertices along the cube edges
    uniq, inv = np.unique(np.round(verts, 9), axis=0, return_inverse=True)
    faces = inv.reshape(-1)[faces]
    faces = faces[(faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])]
    return uniq, faces


def load_shape_file(path: Path, units: str) -> GlobalShape:
    """Read a user's shape model → :class:`GlobalShape` (m), faces oriented outward.

    Parameters
    ----------
    path : pathlib.Path
        OBJ, PLY, STL or GLB (read by :func:`renderlab.render.mesh_io.load_mesh`) or Gaskell ICQ
        (``.icq`` / ``.txt``, read here).
    units : str
        Length unit of the file (``m``, ``km`` or ``cm``).

    Returns
    -------
    GlobalShape
        Vertices in metres, faces counter-clockwise seen from outside, uniform relative albedo.
    """
    from renderlab.render.mesh_io import FORMATS, load_mesh

    suffix = path.suffix.lower()
    if suffix in FORMATS:
        mesh = load_mesh(path, units=units, where="world.shape_file")
        v, f = mesh.vertices, mesh.faces
    elif suffix in (".icq", ".txt"):
        if not path.is_file():
            raise UserError(f"world.shape_file: shape model not found: {path}")
        try:
            v, f = _read_icq(path)
        except (ValueError, IndexError, UnicodeDecodeError) as exc:
            raise UserError(f"world.shape_file: cannot read {path.name}: {exc}") from None
        v = v * {"km": 1000.0, "cm": 0.01}.get(units, 1.0)
    else:
        raise UserError(f"world.shape_file: {path.name} is not an OBJ, PLY, STL, GLB or ICQ shape model")
    if len(v) < 4 or len(f) < 4 or f.min() < 0 or f.max() >= len(v) or not np.all(np.isfinite(v)):
        raise UserError(f"world.shape_file: {path.name} has no valid closed triangle mesh")
    shape = GlobalShape(np.asarray(v, float), np.asarray(f).astype(np.int32), np.ones(len(v), np.float32))
    if shape.volume() < 0:  # inward-facing winding
        shape.faces = shape.faces[:, ::-1].copy()
    return shape
