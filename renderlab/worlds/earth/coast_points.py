r"""Coastline points for the geometric coastline-navigation study: GSHHG vertices, thinned, indexed.

The paper (Straub & Christian, Fig. 2b) matches "identified coastline points" inside the camera
footprint to a georeferenced database. Here the database is the real full-resolution GSHHG coastline
(:func:`renderlab.worlds.earth.gshhg.load_gshhg`, seams along the antimeridian and the south pole removed),
placed on the WGS-84 ellipsoid at zero height and thinned to at most one point per cube of side
``spacing_m`` (first vertex in file order wins, so the result is deterministic). A ``cKDTree`` over the
ECEF points answers "which points lie near this sub-satellite point" in microseconds.

The geometric study treats these points as exact (no map error): it is the paper's idealised mode.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np

from renderlab.worlds.earth import wgs84
from renderlab.worlds.earth.gshhg import load_gshhg

_LOCK = threading.Lock()
_CACHE: dict[float, "CoastlinePoints"] = {}

__all__ = ["CoastlinePoints", "coastline_points"]


@dataclass
class CoastlinePoints:
    """Thinned coastline database: ECEF points (n, 3) in metres, their outward ellipsoid normals and a KD-tree."""

    ecef_m: np.ndarray
    normal: np.ndarray
    tree: object  # scipy.spatial.cKDTree over ecef_m
    spacing_m: float


def _thin(xyz: np.ndarray, spacing_m: float) -> np.ndarray:
    """Indices of the first point in each cube of side spacing_m (sorted, deterministic)."""
    key = np.floor(xyz / spacing_m).astype(np.int64) + (1 << 20)
    flat = (key[:, 0] << 42) | (key[:, 1] << 21) | key[:, 2]
    _, first = np.unique(flat, return_index=True)
    return np.sort(first)


def coastline_points(spacing_m: float = 2000.0) -> CoastlinePoints:
    """The process-wide thinned GSHHG coastline (first call ≈10 s: GSHHG load, thinning, KD-tree)."""
    spacing_m = float(spacing_m)
    with _LOCK:
        if spacing_m not in _CACHE:
            import shapely
            from scipy.spatial import cKDTree


            lonlat = shapely.get_coordinates(load_gshhg().coast)
            xyz = wgs84.geodetic_to_ecef(np.radians(lonlat[:, 1]), np.radians(lonlat[:, 0]))
            xyz = xyz[_thin(xyz, spacing_m)]
            n = xyz / np.array([wgs84.A**2, wgs84.A**2, wgs84.B**2])
            n /= np.linalg.norm(n, axis=1, keepdims=True)
            _CACHE[spacing_m] = CoastlinePoints(xyz, n, cKDTree(xyz), spacing_m)
        return _CACHE[spacing_m]
