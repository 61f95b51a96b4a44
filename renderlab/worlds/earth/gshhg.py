"""GSHHG full-resolution land polygons (shipped in ``roaring-landmask``), loaded once and spatially indexed.

The polygons are GSHHG level 1 (land/ocean boundary), 180k polygons and 9.5M vertices in lon/lat degrees
(WGS-84). Two indexed views are built on first use and cached per process:

* ``land``: the polygons and a shapely STRtree over them (albedo rasterisation);
* ``coast``: the coastline as polylines of at most :data:`CHUNK` segments each, with the artificial edges
  of the data removed (polygons are cut along the antimeridian and Antarctica is closed along the
  south pole); short chunks let the STRtree's bounding boxes do the work, so a footprint query touches
  only the few hundred vertices near it instead of a continent.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np

CHUNK = 64  # segments per coastline chunk
_LOCK = threading.Lock()
_CACHE: dict = {}


@dataclass
class GSHHG:
    land: np.ndarray  # shapely Polygons, lon/lat deg
    land_tree: object  # shapely.STRtree over land
    coast: np.ndarray  # shapely LineStrings (chunks), lon/lat deg
    coast_tree: object  # shapely.STRtree over coast

    def coast_coords(self) -> tuple[np.ndarray, np.ndarray]:
        """All chunk vertices (K, 2) lon/lat and offsets (n_chunks + 1,): chunk c is xy[start[c]:start[c+1]]."""
        if not hasattr(self, "_coords"):
            import shapely

            xy, which = shapely.get_coordinates(self.coast, return_index=True)
            start = np.searchsorted(which, np.arange(len(self.coast) + 1))
            self._coords = (xy, start)
        return self._coords

    def land_in(self, region) -> np.ndarray:
        """Land polygons clipped to ``region`` (a shapely geometry in lon/lat)."""
        import shapely

        idx = self.land_tree.query(region, predicate="intersects")
        return shapely.intersection(self.land[idx], region)

    def coast_in(self, region) -> np.ndarray:
        """Coastline pieces (LineStrings/MultiLineStrings) clipped to ``region``."""
        import shapely

        idx = self.coast_tree.query(region, predicate="intersects")
        out = shapely.intersection(self.coast[idx], region)
        return out[~shapely.is_empty(out)]


def _coast_chunks(polys: np.ndarray) -> np.ndarray:
    """Exterior rings → polylines without artificial seams, cut every CHUNK segments (vectorised)."""
    import shapely

    rings = shapely.get_exterior_ring(polys)
    xy, ring_of = shapely.get_coordinates(rings, return_index=True)
    # a segment joins vertex k and k+1 of the same ring
    same = ring_of[:-1] == ring_of[1:]
    a, b = xy[:-1], xy[1:]
    seam = ((np.abs(a[:, 0]) >= 180.0 - 1e-9) & (np.abs(b[:, 0]) >= 180.0 - 1e-9)) | \
           ((a[:, 1] <= -90.0 + 1e-6) | (b[:, 1] <= -90.0 + 1e-6))
    good = same & ~seam
    seg = np.flatnonzero(good)
    prev_good = np.zeros(len(good), bool)
    prev_good[1:] = good[:-1]
    run_start = ~prev_good[seg]
    run_id = np.cumsum(run_start) - 1
    first_of_run = seg[run_start]
    pos = seg - first_of_run[run_id]
    new_line = run_start | (pos % CHUNK == 0)
    line_id = np.cumsum(new_line) - 1
    last = np.ones(len(seg), bool)
    last[:-1] = line_id[1:] != line_id[:-1]
    # vertices: every segment's start, plus the end of each line's last segment
    starts = seg
    ends = seg[last] + 1
    v_idx = np.concatenate([starts, ends])
    v_line = np.concatenate([line_id, line_id[last]])
    v_order = np.concatenate([np.arange(len(seg)) * 2, np.flatnonzero(last) * 2 + 1])
    o = np.lexsort((v_order, v_line))
    return shapely.linestrings(xy[v_idx[o]], indices=v_line[o])


def load_gshhg() -> GSHHG:
    """The process-wide GSHHG (≈5-8 s on first call, then free)."""
    with _LOCK:
        if "g" not in _CACHE:
            import shapely
            from roaring_landmask import LandmaskProvider, Shapes

            mp = shapely.from_wkb(Shapes.wkb(LandmaskProvider.Gshhg))
            land = np.asarray(mp.geoms)
            coast = _coast_chunks(land)
            _CACHE["g"] = GSHHG(land, shapely.STRtree(land), coast, shapely.STRtree(coast))
        return _CACHE["g"]
