"""The lab's one mesh reader: OBJ, PLY (ASCII and binary), STL and GLB files → an in-memory triangle mesh.

Every world and both renderers read mesh files through :func:`load_mesh` (trimesh underneath), so one
library decides what a file means:

* Formats by extension: ``.obj`` (Wavefront, ``v``/``vt``/``f``), ``.ply`` (ASCII, binary little- or
  big-endian; ``vertex`` x y z, optional s/t or u/v texture coordinates), ``.stl`` (ASCII or binary) and
  ``.glb`` (binary glTF 2.0; every mesh of the scene graph with its node transforms applied, concatenated).
  Coordinates are used as stored: no axis conversion (glTF's +Y-up stays +Y of the body frame) — orient
  the body with ``rotation_deg``.
* Polygons: quads are split along their 0–2 diagonal, larger polygons into fans (trimesh's
  ``triangulate_quads``), keeping each polygon's winding.
* Units: ``units`` (``m``, ``km`` or ``cm``: metres per file unit 1, 1000, 0.01) times ``scale``.
* Validation (one-line :class:`~renderlab.errors.UserError` naming the file): readable, at least one
  face, every coordinate finite, face indices in range. Degenerate faces (a repeated vertex, or
  collinear vertices: ‖e₁ × e₂‖ ≤ 1e-12 · (longest edge)²) are removed and counted, unreferenced vertices
  dropped. Watertightness is reported (:attr:`TriangleMesh.watertight`), not required.
* Normals: ``flat`` (facet normals; the renderers shade each triangle flat, ``vertex_normals`` is None)
  or ``smooth``: per-vertex unit normals, the area-weighted mean of the facet normals around each
  vertex position (coincident vertices — STL's, or uv seams — share one normal).
* Texture coordinates (OBJ ``vt``, PLY s/t, glTF TEXCOORD_0) come back in the lab's convention
  (:class:`~renderlab.render.scene.BodySpec`: v from the map's top row down), i.e. v_lab = 1 − v_file as
  in OBJ/Blender (image bottom at v = 0); Mitsuba's own OBJ loader flips the same way.

Gaskell ICQ shape models keep their own reader (:mod:`renderlab.worlds.ev5.shape`).
"""

from __future__ import annotations

import dataclasses
import logging
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from renderlab.errors import UserError
from renderlab.inputs import LIMITS, check_regular, short, shown

#: metres per file unit
UNITS_M = {"m": 1.0, "km": 1000.0, "cm": 0.01}
#: file extension → trimesh file type
FORMATS = {".obj": "obj", ".ply": "ply", ".stl": "stl", ".glb": "glb"}
NORMALS = ("flat", "smooth")
COLLINEAR_EPS = 1e-12

# trimesh logs through the 'trimesh' logger; without a handler Python would print its warnings on
# stderr (the command line promises one line there). They still reach an application's root handlers.
logging.getLogger("trimesh").addHandler(logging.NullHandler())


@dataclass(frozen=True)
class TriangleMesh:
    """A validated triangle mesh in metres (the body frame of the file).

    Attributes
    ----------
    vertices : numpy.ndarray
        (V, 3) float64 positions, m.
    faces : numpy.ndarray
        (F, 3) int64 vertex indices, winding as in the file.
    vertex_normals : numpy.ndarray or None
        (V, 3) float64 unit normals (``normals = "smooth"``), None for flat shading.
    vertex_uv : numpy.ndarray or None
        (V, 2) float64 texture coordinates in the lab's convention, None if the file has none.
    n_degenerate : int
        Faces removed as degenerate.
    watertight : bool
        Every edge is shared by exactly two faces (after merging coincident vertices).
    source : str
        File name, for messages.
    """

    vertices: np.ndarray
    faces: np.ndarray
    vertex_normals: np.ndarray | None = None
    vertex_uv: np.ndarray | None = None
    n_degenerate: int = 0
    watertight: bool = False
    source: str = ""


def _read(path: Path, where: str):
    """trimesh's mesh of ``path`` (one mesh, scene graph flattened) or a one-line UserError."""
    import trimesh

    kind = FORMATS.get(path.suffix.lower())
    if kind is None:
        raise UserError(f"{where}: {path.name} is not a supported mesh file (OBJ, PLY, STL or GLB by extension)")
    if not os.path.lexists(path):
        raise UserError(f"{where}: mesh not found: {shown(path)}")
    check_regular(path, f"{where}: mesh", LIMITS["mesh"])  # a regular file of bounded size: no FIFO, no device
    try:
        mesh = trimesh.load(str(path), file_type=kind, force="mesh", process=False)
    except Exception as exc:  # noqa: BLE001 - any parser failure is the file's fault
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise UserError(f"{where}: cannot read {path.name} as {kind.upper()}: {msg}") from None
    if not hasattr(mesh, "faces") or not hasattr(mesh, "vertices"):
        raise UserError(f"{where}: {path.name} holds no triangle mesh")
    return mesh


def _uv_of(mesh, n_vertices: int) -> np.ndarray | None:
    uv = getattr(getattr(mesh, "visual", None), "uv", None)
    if uv is None or np.shape(uv) != (n_vertices, 2):
        return None
    uv = np.array(uv, np.float64)
    uv[:, 1] = 1.0 - uv[:, 1]
    return uv if np.all(np.isfinite(uv)) else None


def _drop_degenerate(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, int]:
    """Faces without a repeated vertex and with ‖e₁ × e₂‖ > eps·(longest edge)²; and how many went."""
    T = V[F]
    e = np.stack([T[:, 1] - T[:, 0], T[:, 2] - T[:, 1], T[:, 0] - T[:, 2]], axis=1)
    longest2 = (e ** 2).sum(-1).max(axis=1)
    area2 = np.linalg.norm(np.cross(e[:, 0], -e[:, 2]), axis=1)
    repeated = (F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 0] == F[:, 2])
    keep = ~repeated & (area2 > COLLINEAR_EPS * longest2)
    return F[keep], int((~keep).sum())


def _position_groups(V: np.ndarray) -> np.ndarray:
    """Index of each vertex's position among the distinct positions (coincident vertices share one)."""
    _, inv = np.unique(V, axis=0, return_inverse=True)
    return inv.reshape(-1)


def smooth_normals(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals, shared by coincident vertices (module docstring)."""
    group = _position_groups(V)
    acc = np.zeros((group.max() + 1, 3))
    fn = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])  # length = 2 × area
    for k in range(3):
        np.add.at(acc, group[F[:, k]], fn)
    n = acc[group]
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    return np.where(norm > 0, n / np.where(norm > 0, norm, 1.0), 0.0)


def _watertight(V: np.ndarray, F: np.ndarray) -> bool:
    g = _position_groups(V)[F]
    e = np.sort(np.concatenate([g[:, [0, 1]], g[:, [1, 2]], g[:, [2, 0]]]), axis=1)
    _, counts = np.unique(e, axis=0, return_counts=True)
    return bool(len(counts) and np.all(counts == 2))


def load_mesh(path: str | Path, *, units: str = "m", scale: float = 1.0, normals: str = "flat",
              where: str = "mesh") -> TriangleMesh:
    """Read a mesh file into a validated :class:`TriangleMesh` (module docstring).

    Parameters
    ----------
    path : str or pathlib.Path
        OBJ, PLY, STL or GLB file.
    units : {"m", "km", "cm"}
        Length unit of the file's coordinates.
    scale : float
        Extra factor applied after ``units`` (positive, finite).
    normals : {"flat", "smooth"}
        Shading normals (module docstring).
    where : str
        Prefix of error messages (the scenario key, e.g. ``world.bodies.2.file``).

    Returns
    -------
    TriangleMesh
        Vertices in metres, triangles, optional normals and uv.

    Raises
    ------
    UserError
        Unknown extension, missing or unreadable file, no faces, non-finite coordinates, bad indices.
    """
    path = Path(path)
    if units not in UNITS_M:
        raise UserError(f"{where}: units must be one of {', '.join(UNITS_M)}, got {short(units)}")
    if normals not in NORMALS:
        raise UserError(f"{where}: normals must be 'flat' or 'smooth', got {short(normals)}")
    if not (np.isfinite(scale) and scale > 0):
        raise UserError(f"{where}: scale must be a positive finite number, got {scale}")
    mesh = _read(path, where)
    V = np.array(mesh.vertices, np.float64).reshape(-1, 3)
    F = np.array(mesh.faces, np.int64).reshape(-1, 3)
    if len(F) == 0:
        raise UserError(f"{where}: {path.name} has no faces")
    if F.min() < 0 or F.max() >= len(V):
        raise UserError(f"{where}: {path.name} has face indices outside its {len(V)} vertices")
    if not np.all(np.isfinite(V)):
        raise UserError(f"{where}: {path.name} has non-finite vertex coordinates")
    uv = _uv_of(mesh, len(V))
    F, n_bad = _drop_degenerate(V, F)
    if len(F) == 0:
        raise UserError(f"{where}: {path.name} has only degenerate faces ({n_bad})")
    used = np.unique(F)
    remap = np.full(len(V), -1, np.int64)
    remap[used] = np.arange(len(used))
    V, F = V[used] * (UNITS_M[units] * float(scale)), remap[F]
    uv = None if uv is None else uv[used]
    vn = smooth_normals(V, F) if normals == "smooth" else None
    return TriangleMesh(vertices=V, faces=F, vertex_normals=vn, vertex_uv=uv, n_degenerate=n_bad,
                        watertight=_watertight(V, F), source=path.name)


def mesh_body(body, mesh: TriangleMesh | None = None):
    """A ``shape = "mesh"`` :class:`~renderlab.render.scene.BodySpec` as the in-memory ``trimesh`` body.

    Parameters
    ----------
    body : BodySpec
        A ``mesh`` body (``mesh_path`` in metres; ``face_normals`` False → smooth normals), or any other
        body, which is returned unchanged.
    mesh : TriangleMesh, optional
        The mesh already read (else ``body.mesh_path`` is read here).

    Returns
    -------
    BodySpec
        ``shape = "trimesh"`` with vertices, faces, normals and (with an albedo map) uv.
    """
    if body.shape != "mesh":
        return body
    if mesh is None:
        mesh = load_mesh(body.mesh_path, normals="flat" if body.face_normals else "smooth",
                         where=f"body '{body.name}'")
    if body.albedo_map is not None and mesh.vertex_uv is None:
        raise UserError(f"body '{body.name}': albedo_map needs texture coordinates, {mesh.source} has none")
    return dataclasses.replace(body, shape="trimesh", vertices=mesh.vertices, faces=mesh.faces,
                               vertex_normals=mesh.vertex_normals,
                               vertex_uv=mesh.vertex_uv if body.albedo_map is not None else body.vertex_uv)
