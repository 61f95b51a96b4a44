r"""The onboard coastline database: a degraded copy of GSHHG for the estimators.

GSHHG is within 100 m of Landsat coastlines for only ~9 % of the coast, so an onboard map has errors of a
few hundred metres. This copy is (1) simplified (Douglas-Peucker) to ``tolerance_m`` (in degrees of
latitude, 1° = 111.32 km; longitude tolerance is the same angle, i.e. tighter by cos φ), then (2) displaced
by a smooth, seeded random field (east, north) of ``error_m`` 1σ per axis (the random-phase wave sum of
:mod:`.clouds`, wave scales ``scale_m``/2 … 4·``scale_m``), so nearby points share their error like a real
map's. Measured with the default ``scale_m`` = 100 km over Iberia, 24 seeds (``tests/test_earth_coast_db.py``
and its probe): per-axis RMS 282-296 m for 300 m set; correlation of two vertices' displacements 0.99 within
50 km, 0.84 at 50-150 km, 0.38 at 150-400 km, 0.10 beyond 400 km, so across one 540 km footprint the error is
largely common. Output: polylines ``segment_id, lon_deg, lat_deg, x/y/z_ecef_m`` (WGS-84, height 0);
:func:`coast_db_ecef`: the ECEF points of one realisation over a lon/lat box, cached.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from renderlab.worlds.earth import wgs84
from renderlab.worlds.earth.clouds import CloudField
from renderlab.worlds.earth.gshhg import load_gshhg

M_PER_DEG = 111320.0


@dataclass(frozen=True)
class CoastDBOptions:
    tolerance_m: float = 150.0
    error_m: float = 300.0
    scale_m: float = 100e3
    seed: int = 0


def build_coast_db(gshhg, region, opt: CoastDBOptions) -> dict[str, np.ndarray]:
    """Columns of the degraded database restricted to ``region`` (lon/lat shapely geometry)."""
    import shapely

    lines = gshhg.coast_in(region)
    parts = shapely.get_parts(lines)
    parts = parts[shapely.get_type_id(parts) == 1]
    merged = shapely.get_parts(shapely.line_merge(shapely.multilinestrings(parts))) if len(parts) else parts
    if opt.tolerance_m > 0 and len(merged):
        merged = shapely.simplify(merged, opt.tolerance_m / M_PER_DEG, preserve_topology=False)
    xy, seg = shapely.get_coordinates(merged, return_index=True) if len(merged) else (np.zeros((0, 2)), np.zeros(0, int))
    lat, lon = np.radians(xy[:, 1]), np.radians(xy[:, 0])
    p = wgs84.geodetic_to_ecef(lat, lon)
    if opt.error_m > 0 and len(xy):
        de = CloudField(0.5, opt.seed * 2 + 1, opt.scale_m / 2, opt.scale_m * 4).value(p) * opt.error_m
        dn = CloudField(0.5, opt.seed * 2 + 2, opt.scale_m / 2, opt.scale_m * 4).value(p) * opt.error_m
        enu = wgs84.R_ecef_from_enu(lat, lon)
        p = p + de[:, None] * enu[..., 0] + dn[:, None] * enu[..., 1]
        lat, lon, h = wgs84.ecef_to_geodetic(p)
        p = wgs84.geodetic_to_ecef(lat, lon)  # back on the ellipsoid
    return {"segment_id": seg.astype(np.int64), "lon_deg": np.degrees(lon), "lat_deg": np.degrees(lat),
            "x_ecef_m": p[:, 0], "y_ecef_m": p[:, 1], "z_ecef_m": p[:, 2]}


@functools.lru_cache(maxsize=4)
def coast_db_ecef(bounds: tuple, opt: CoastDBOptions) -> np.ndarray:
    """ECEF points (n, 3) of the database of one realisation ``opt`` over the lon/lat box ``bounds``
    (lon_min, lat_min, lon_max, lat_max in degrees); the last few are cached."""
    import shapely

    cols = build_coast_db(load_gshhg(), shapely.box(*bounds), opt)
    return np.stack([cols["x_ecef_m"], cols["y_ecef_m"], cols["z_ecef_m"]], -1)
