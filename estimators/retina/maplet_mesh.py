r"""Maplet pre-processing (Retina "Maplet Pre-Processing"): DEM → facets, normals, acceleration grid.

The maplet DEM is a regular ``n × n`` height field (see :class:`renderlab.geometry.Maplet`). Each grid
cell (row j, column i) is split along its (j, i)–(j+1, i+1) diagonal into two triangles,

    tri 0 = (j, i), (j, i+1), (j+1, i+1)      tri 1 = (j, i), (j+1, i+1), (j+1, i),

counter-clockwise seen from +z (maplet "up"), so the facet normals point up. The paper allows a
Delaunay triangulation of the DEM; on a regular grid this diagonal split is one (the grid's points are
co-circular in each cell, so every diagonal choice is Delaunay in the xy-plane).

Acceleration structure: the regular grid itself, with the minimum and maximum height of every cell.
A ray is clipped to the maplet's bounding box and walked cell by cell with a 2-D DDA (Amanatides &
Woo 1987); only cells whose height interval overlaps the ray's height interval over that cell are
tested against their two triangles (Möller–Trumbore). The first cell with a hit holds the nearest hit,
because cells are visited in order of the ray parameter. A coarse level (min / max height of 8 × 8-cell
blocks) is walked first, so rays skip whole blocks they pass above or below (shadow rays leaving the
terrain, oblique lines of sight). See :mod:`.raytrace`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from estimators.retina.raytrace import BLOCK, block_bounds
from renderlab.geometry.maplet import Maplet


@dataclass(frozen=True)
class MapletMesh:
    """A maplet triangulated for ray casting (built once per maplet).

    Attributes
    ----------
    maplet : Maplet
        The source maplet.
    heights : numpy.ndarray
        (n, n) float64 heights, m (C-contiguous, for the kernels).
    albedo : numpy.ndarray
        (n, n) float64 relative albedo.
    normals : numpy.ndarray
        (n−1, n−1, 2, 3) unit facet normals in the maplet frame (tri 0, tri 1 of each cell).
    cell_min, cell_max : numpy.ndarray
        (n−1, n−1) min / max height of each cell's four corners, m.
    block_min, block_max : numpy.ndarray
        Min / max height of every ``BLOCK × BLOCK`` block of cells (coarse level of the two-level grid).
    points_body : numpy.ndarray
        (n, n, 3) grid points in the body frame (for projecting the maplet with a pose).
    """

    maplet: Maplet
    heights: np.ndarray
    albedo: np.ndarray
    normals: np.ndarray
    cell_min: np.ndarray
    cell_max: np.ndarray
    block_min: np.ndarray
    block_max: np.ndarray
    points_body: np.ndarray

    @property
    def n(self) -> int:
        return self.maplet.n

    @property
    def spacing(self) -> float:
        return float(self.maplet.spacing_m)

    def vertices_faces(self) -> tuple[np.ndarray, np.ndarray]:
        """All facets as (V, 3) maplet-frame vertices and (F, 3) faces, in the kernels' order:
        face ``2 (j (n−1) + i) + k`` is triangle k of cell (j, i)."""
        n = self.n
        V = self.maplet.points_maplet().reshape(-1, 3)
        j, i = np.meshgrid(np.arange(n - 1), np.arange(n - 1), indexing="ij")
        a, b = (j * n + i).ravel(), (j * n + i + 1).ravel()
        c, d = ((j + 1) * n + i + 1).ravel(), ((j + 1) * n + i).ravel()
        F = np.stack([np.stack([a, b, c], -1), np.stack([a, c, d], -1)], axis=1).reshape(-1, 3)
        return V, F


def build_mesh(maplet: Maplet) -> MapletMesh:
    """Triangulate a maplet, compute facet normals and the per-cell height bounds."""
    h = np.ascontiguousarray(maplet.heights_m, dtype=np.float64)
    s = float(maplet.spacing_m)
    hA, hB, hC, hD = h[:-1, :-1], h[:-1, 1:], h[1:, 1:], h[1:, :-1]
    # tri 0: A B C, e1 = B − A = (s, 0, hB − hA), e2 = C − A = (s, s, hC − hA)
    n0 = np.stack([-s * (hB - hA), s * (hB - hA) - s * (hC - hA), np.full_like(hA, s * s)], axis=-1)
    # tri 1: A C D, e1 = C − A = (s, s, hC − hA), e2 = D − A = (0, s, hD − hA)
    n1 = np.stack([s * (hD - hA) - s * (hC - hA), -s * (hD - hA), np.full_like(hA, s * s)], axis=-1)
    normals = np.stack([n0, n1], axis=2)
    normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
    cmin = np.minimum(np.minimum(hA, hB), np.minimum(hC, hD))
    cmax = np.maximum(np.maximum(hA, hB), np.maximum(hC, hD))
    cmin, cmax = np.ascontiguousarray(cmin), np.ascontiguousarray(cmax)
    bmin, bmax = block_bounds(cmin, cmax, BLOCK)
    return MapletMesh(maplet=maplet, heights=h, albedo=np.ascontiguousarray(maplet.albedo, dtype=np.float64),
                      normals=np.ascontiguousarray(normals), cell_min=cmin, cell_max=cmax, block_min=bmin,
                      block_max=bmax, points_body=np.ascontiguousarray(maplet.points_body(), dtype=np.float64))
