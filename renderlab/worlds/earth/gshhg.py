"""GSHHG full-resolution land polygons (shipped in ``roaring-landmask``), loaded once and spatially indexed.

The polygons are GSHHG level 1 (land/ocean boundary), 180k polygons and 9.5M vertices in lon/lat degrees
(WGS-84). :func:`load_gshhg` parses them once per process; the indexed views are built on first use:

* ``land``/``land_tree``: the polygons and a shapely STRtree over them (albedo rasterisation);
* ``coast``/``coast_tree``: the coastline as polylines of at most :data:`CHUNK` segments each, with the
  artificial edges of the data removed (polygons are cut along the antimeridian and Antarctica is closed
  along the south pole); short chunks let the STRtree's bounding boxes do the work, so a footprint query
  touches only the few hundred vertices near it instead of a continent.

Everything is vectorised shapely 2 / numpy (``get_parts`` rather than iterating ``MultiPolygon.geoms``;
chunk vertices by index arithmetic, no sort).
"""

from __future__ import annotations

import threading
import numpy as np

CHUNK = 64  # segments per coastline chunk
_LOCK = threading.Lock()
_CACHE: dict = {}


class GSHHG:
    """GSHHG level-1 land polygons with lazily built STRtrees and coastline chunks (thread-safe)."""

    def __init__(self, land: np.ndarray):
        self.land = land  # shapely Polygons, lon/lat deg
        self._lock = threading.RLock()

    def _once(self, name: str, build):
        """``build()`` stored as ``name`` on first use (one builder at a time)."""
        if name not in self.__dict__:
            with self._lock:
                if name not in self.__dict__:
                    self.__dict__[name] = build()
        return self.__dict__[name]

    @property
    def land_tree(self):
        """shapely.STRtree over :attr:`land`."""
        import shapely

        return self._once("_land_tree", lambda: shapely.STRtree(self.land))

    @property
    def coast(self) -> np.ndarray:
        """Coastline chunks: shapely LineStrings, lon/lat deg."""
        return self._once("_coast", lambda: _coast_chunks(self.land))

    @property
    def coast_tree(self):
        """shapely.STRtree over :attr:`coast`."""
        import shapely

        return self._once("_coast_tree", lambda: shapely.STRtree(self.coast))

    def coast_coords(self) -> tuple[np.ndarray, np.ndarray]:
        """All chunk vertices (K, 2) lon/lat and offsets (n_chunks + 1,): chunk c is xy[start[c]:start[c+1]]."""
        import shapely

        def build():
            xy, which = shapely.get_coordinates(self.coast, return_index=True)
            return xy, np.searchsorted(which, np.arange(len(self.coast) + 1))

        return self._once("_coords", build)

    def land_in(self, region) -> np.ndarray:
        """Land polygons clipped to ``region`` (a shapely geometry in lon/lat)."""
        import shapely

        idx = self.land_tree.query(region, predicate="intersects")
        return shapely.intersection(self.land[idx], region)

    def coast_in(self, region) -> np.ndarray:
        """Coastline pieces (LineStrings/MultiLineStrings) clipped to ``region``.

        Built from the chunks of only the land polygons that meet ``region`` (cached per polygon), so a
        render never pays for the global coastline index; the chunks are those of :attr:`coast`."""
        import shapely

        idx = np.sort(self.land_tree.query(region, predicate="intersects"))
        if len(idx) == 0:
            return np.empty(0, dtype=object)
        cache = self._once("_poly_chunks", dict)
        with self._lock:
            for i in idx:
                if i not in cache:
                    cache[i] = _coast_chunks(self.land[i:i + 1])
        chunks = np.concatenate([cache[i] for i in idx])
        shapely.prepare(region)
        out = shapely.intersection(chunks[shapely.intersects(region, chunks)], region)
        return out[~shapely.is_empty(out)]


def _coast_chunks(polys: np.ndarray) -> np.ndarray:
    """Exterior rings → polylines without artificial seams, cut every CHUNK segments (vectorised)."""
    import shapely

    xy, ring_of = shapely.get_coordinates(shapely.get_exterior_ring(polys), return_index=True)
    # segment k joins vertex k and k+1 of the same ring; drop seams (antimeridian cut, south-pole closure)
    a, b = xy[:-1], xy[1:]
    seam = ((np.abs(a[:, 0]) >= 180.0 - 1e-9) & (np.abs(b[:, 0]) >= 180.0 - 1e-9)) | \
           ((a[:, 1] <= -90.0 + 1e-6) | (b[:, 1] <= -90.0 + 1e-6))
    good = (ring_of[:-1] == ring_of[1:]) & ~seam
    seg = np.flatnonzero(good)
    run_start = np.ones(len(seg), bool)  # a run is a maximal stretch of consecutive good segments
    run_start[1:] = seg[1:] != seg[:-1] + 1
    run_first = np.maximum.accumulate(np.where(run_start, np.arange(len(seg)), 0))
    new_line = run_start | ((np.arange(len(seg)) - run_first) % CHUNK == 0)
    first = seg[new_line]  # first segment of each line
    n_seg = np.diff(np.append(np.flatnonzero(new_line), len(seg)))
    n_vert = n_seg + 1  # a line's segments are consecutive, so are its vertices: first .. first + n_seg
    v = np.repeat(first - np.cumsum(np.r_[0, n_vert[:-1]]), n_vert) + np.arange(n_vert.sum())
    return shapely.linestrings(xy[v], indices=np.repeat(np.arange(len(first)), n_vert))


def load_gshhg() -> GSHHG:
    """The process-wide GSHHG (parsed on first call, ≈ 6 s; the indexes on first use)."""
    with _LOCK:
        if "g" not in _CACHE:
            from renderlab.extras import require

            shapely = require("shapely", "earth")
            require("roaring_landmask", "earth")
            from roaring_landmask import LandmaskProvider, Shapes

            _CACHE["g"] = GSHHG(shapely.get_parts(shapely.from_wkb(Shapes.wkb(LandmaskProvider.Gshhg))))
        return _CACHE["g"]
