"""The onboard coastline database: a degraded copy of full-resolution GSHHG (simplified, then displaced by a
smooth seeded map error), over Iberia.

Oracles: the distance of every full-resolution vertex to the simplified polylines (shapely STRtree nearest query;
Douglas-Peucker bounds it by the tolerance); the displacement of each vertex against the undisplaced simplified copy, resolved on
the local east/north axes and pooled over seeds (its per-axis RMS must be the set 1σ map error: the field is
N(0, 1) at every point, so the pooled mean square is unbiased whatever the correlation); the correlation of the
displacements of vertex pairs against their distance (a smooth map error: near points move together).
"""

from __future__ import annotations

import earth_fixtures
import numpy as np
import pytest
from scipy.spatial import cKDTree

from renderlab.worlds.earth import wgs84
from renderlab.worlds.earth.coast_db import M_PER_DEG, CoastDBOptions, build_coast_db

gshhg = earth_fixtures.gshhg
ERROR_M, TOL_M, SEEDS = 300.0, 150.0, 24


@pytest.fixture(scope="module")
def region():
    import shapely

    return shapely.box(-10.0, 36.0, 4.0, 44.0)   # Iberia: ≈ 1200 x 900 km, 54k GSHHG vertices


def _xyz(db):
    return np.stack([db["x_ecef_m"], db["y_ecef_m"], db["z_ecef_m"]], -1)


def _lines(db):
    import shapely

    seg = db["segment_id"]
    assert np.all(np.diff(seg) >= 0)                           # vertices grouped by polyline
    keep = np.isin(seg, np.flatnonzero(np.bincount(seg) > 1))
    return shapely.linestrings(np.c_[db["lon_deg"], db["lat_deg"]][keep], indices=seg[keep])


def test_simplified_within_tolerance_of_full_resolution(gshhg, region):
    import shapely

    full = build_coast_db(gshhg, region, CoastDBOptions(0.0, 0.0))
    simp = build_coast_db(gshhg, region, CoastDBOptions(TOL_M, 0.0))
    n_full, n_simp = len(full["lon_deg"]), len(simp["lon_deg"])
    tree = shapely.STRtree(_lines(simp))
    _, dist = tree.query_nearest(shapely.points(full["lon_deg"], full["lat_deg"]), return_distance=True, all_matches=False)
    hd = float(dist.max())
    print(f"vertices: full {n_full}, simplified {n_simp}; farthest full-resolution vertex {hd * M_PER_DEG:.1f} m "
          f"(lat-degree metres), tolerance {TOL_M} m")
    assert n_full > 20000 and n_simp < 0.3 * n_full            # measured 54463 → 10676
    assert hd <= TOL_M / M_PER_DEG * (1 + 1e-6)
    assert hd > 0.5 * TOL_M / M_PER_DEG                        # it did simplify up to the tolerance
    _, _, h = wgs84.ecef_to_geodetic(_xyz(simp))
    assert np.abs(h).max() < 1e-3                              # on the ellipsoid


def test_map_error_has_the_set_size_and_is_smooth(gshhg, region):
    ref = build_coast_db(gshhg, region, CoastDBOptions(TOL_M, 0.0))
    p0 = _xyz(ref)
    enu = wgs84.R_ecef_from_enu(np.radians(ref["lat_deg"]), np.radians(ref["lon_deg"]))
    disp = []
    for seed in range(SEEDS):
        db = build_coast_db(gshhg, region, CoastDBOptions(TOL_M, ERROR_M, 100e3, seed))
        assert np.array_equal(db["segment_id"], ref["segment_id"])     # same vertices, displaced
        disp.append(np.einsum("nij,ni->nj", enu, _xyz(db) - p0))
    disp = np.array(disp)                                              # (seeds, n, [e, n, u])
    rms = np.sqrt(np.mean(disp**2, axis=(0, 1)))
    print(f"map error RMS over {SEEDS} seeds: east {rms[0]:.0f} m, north {rms[1]:.0f} m, up {rms[2]:.3f} m "
          f"(set {ERROR_M:.0f} m per axis)")
    assert np.all(np.abs(rms[:2] / ERROR_M - 1) < 0.2) and rms[2] < 0.1   # horizontal, on the ellipsoid
    # smooth: vertex pairs < 3 km apart move together, pairs > 400 km apart nearly independently
    rng = np.random.default_rng(0)
    i, j = rng.integers(0, len(p0), (2, 20000))
    near = cKDTree(p0).query_pairs(3000.0, output_type="ndarray")[:5000]
    def corr(a, b):
        x, y = disp[:, a, :2], disp[:, b, :2]
        return float(np.sum(x * y) / np.sqrt(np.sum(x * x) * np.sum(y * y)))
    far = np.linalg.norm(p0[i] - p0[j], axis=1) > 400e3
    c_near, c_far = corr(near[:, 0], near[:, 1]), corr(i[far], j[far])
    print(f"displacement correlation: pairs < 3 km {c_near:.4f}, pairs > 400 km {c_far:.3f}")
    assert c_near > 0.99 and abs(c_far) < 0.3


def test_map_error_is_seeded(gshhg, region):
    a = build_coast_db(gshhg, region, CoastDBOptions(TOL_M, ERROR_M, 100e3, 3))
    b = build_coast_db(gshhg, region, CoastDBOptions(TOL_M, ERROR_M, 100e3, 3))
    c = build_coast_db(gshhg, region, CoastDBOptions(TOL_M, ERROR_M, 100e3, 4))
    assert all(np.array_equal(a[k], b[k]) for k in a)
    assert np.median(np.linalg.norm(_xyz(a) - _xyz(c), axis=1)) > 50.0
