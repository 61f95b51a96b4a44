"""Per-frame Mitsuba geometry of tiled surfaces (:class:`renderlab.contracts.tiled.TiledSurface`).

Each tiled surface is one Mitsuba mesh of the backend's scene whose buffers hold, per frame, the tiles that
frame needs. A tile's arrays (render-frame float32 vertices shifted by the scene origin in float64, as
:meth:`MitsubaBackend._trimesh` does, faces, per-vertex albedo) are built the first time a frame asks for
it and kept for the rest of the process (scene load paid once per process and per tile). When the set of
tiles differs from the previous frame's, the kept arrays are concatenated and written into the mesh in
place (``mi.traverse``: vertex positions, faces, the ``vertex_albedo`` attribute), which rebuilds only the
acceleration structure; the scene keeps its shapes, so the integrator's kernels stay compiled. Mitsuba rebuilds
the structure of the whole scene, static bodies included: on the full EV5 world (1.30 M global facets) writing
34 k tile facets back unchanged costs 2.0–2.5 s at load 4 (``benchmarks/bench_ev5_descent.py``), so a frame whose
tile set is unchanged writes nothing (a sun-only update costs milliseconds). That is why JIT variants with the
direct-sun integrator keep the tiles in a second scene instead (:mod:`renderlab.render.mitsuba_two_scene`, which
shares :class:`TileArrays`); this one-scene form remains for scalar variants and Mitsuba's ``path`` integrator.

Why one mesh and not one ``mi.Mesh`` per tile: a scene of hundreds of shapes makes every kernel dispatch
over hundreds of shape (and BSDF) instances. Measured on a 361-tile frame of the tiny test world at 128²
(load ≈ 20 on 2 cores): a scene assembled from per-tile meshes cost 3.6 s to load and 1.6–3.8 s per render
vs 0.25–1.6 s for the untiled scene, and one BSDF per tile grew the process past 11 GB.
"""

from __future__ import annotations

import numpy as np

from renderlab.render.mitsuba_rays import aligned_f32
from renderlab.render.scene import BodySpec

#: a surface with no tile in view gets this one degenerate (never hit) triangle
_EMPTY = (np.zeros((3, 3), np.float32), np.array([0, 1, 2], np.uint32), np.ones(3, np.float32))


class TileArrays:
    """Per-tile float32 arrays of the tiled surfaces of one scene, built once per process and tile."""

    def __init__(self, origin: np.ndarray, tiled: list):
        self.origin = np.asarray(origin, np.float64)
        self.tiled = list(tiled)
        self.arrays: dict[tuple[int, object], tuple[np.ndarray, np.ndarray, np.ndarray]] = {}

    def wanted(self, frame) -> tuple:
        """Per surface, the keys of the tiles the frame needs."""
        return tuple(tuple(surf.select(frame.camera, frame.pose)) for surf in self.tiled)

    def _tile(self, k: int, key):
        """(float32 vertices (render frame − origin), uint32 faces, float32 albedo) of one tile, kept."""
        if (k, key) not in self.arrays:
            body = self.tiled[k].tile_body(key)
            V = np.asarray(body.vertices, np.float64) @ np.asarray(body.R_render_from_body, float).T \
                + (np.asarray(body.center_m, float) - self.origin)
            va = np.ones(len(V)) if body.vertex_albedo is None else np.asarray(body.vertex_albedo, np.float64)
            self.arrays[(k, key)] = (V.astype(np.float32), np.asarray(body.faces, np.uint32).ravel(),
                                     (va * float(body.albedo)).astype(np.float32))
        return self.arrays[(k, key)]

    def merged(self, k: int, keys: list) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Concatenated (vertices (V, 3), faces (3F,), albedo (V,)) of surface ``k``'s tiles ``keys``."""
        parts = [self._tile(k, key) for key in keys] or [_EMPTY]
        offsets = np.cumsum([0] + [len(p[0]) for p in parts[:-1]])
        V = np.concatenate([p[0] for p in parts])
        F = np.concatenate([p[1] + np.uint32(o) for p, o in zip(parts, offsets)])
        A = np.concatenate([p[2] for p in parts])
        return V, F, A

    def body(self, k: int, keys: list):
        """Surface ``k``'s tiles ``keys`` as one trimesh body (render frame − origin; centre at the origin)."""
        surf = self.tiled[k]
        V, F, A = self.merged(k, keys)
        return BodySpec(name=surf.name, body_id=surf.body_id, shape="trimesh", center_m=self.origin,
                        R_render_from_body=np.eye(3), law=surf.law, albedo=1.0, vertices=V.astype(np.float64),
                        faces=F.reshape(-1, 3), vertex_albedo=A.astype(np.float64))


    def add_meshes(self, backend, want: tuple, desc: dict, keys: dict) -> None:
        """Put one mesh per surface (``tiled{k}``: the frame's tiles ``want[k]``) into scene dict ``desc`` and its
        body id into ``keys`` (shape key → body id)."""
        for k, surf in enumerate(self.tiled):
            desc[f"tiled{k}"] = backend._trimesh(self.body(k, list(want[k])), f"tiled{k}")
            keys[f"tiled{k}"] = surf.body_id

    def write(self, params, want: tuple, current: tuple) -> None:
        """Write the tiles of every surface whose set changed from ``current`` to ``want`` into the meshes of
        ``params`` (``mi.traverse`` of the scene holding them) and update it (its structure is rebuilt)."""
        for k in range(len(self.tiled)):
            if want[k] == current[k]:
                continue
            V, F, A = self.merged(k, list(want[k]))
            params[f"tiled{k}.vertex_positions"] = type(params[f"tiled{k}.vertex_positions"])(aligned_f32(V))
            params[f"tiled{k}.faces"] = type(params[f"tiled{k}.faces"])(F)
            params[f"tiled{k}.vertex_albedo"] = type(params[f"tiled{k}.vertex_albedo"])(aligned_f32(A))
        params.update()


class TileScenes:
    """The tiled part of one :class:`~renderlab.render.mitsuba_backend.MitsubaBackend`'s scene, merged into it
    (the one-scene design: scalar variants and Mitsuba's ``path`` integrator)."""

    def __init__(self, backend, static_desc: dict, static_keys: dict, tiled: list):
        self.backend = backend
        self.static_desc, self.static_keys = dict(static_desc), dict(static_keys)
        self.tiles = TileArrays(backend.origin, tiled)
        self.current: tuple | None = None
        self.updates = 0  # frames that changed the tile set

    def update(self, frame) -> None:
        """Make the backend's scene hold the static bodies and the frame's tiles."""
        want = self.tiles.wanted(frame)
        if want == self.current:
            return
        b = self.backend
        if self.current is None:  # first frame: the scene with one mesh per surface
            desc, keys = dict(self.static_desc), dict(self.static_keys)
            self.tiles.add_meshes(b, want, desc, keys)
            b._load(desc, keys)
        else:
            self.tiles.write(b.params, want, self.current)
        self.current = want
        self.updates += 1
