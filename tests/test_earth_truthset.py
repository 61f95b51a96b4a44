"""An Earth truth set on disk, read back without the lab: ``renderlab render scenes/earth_leo.toml`` (Portugal,
96 px, Mitsuba), then only ``json``, ``OpenEXR``, ``pyarrow`` and numpy.

Oracles (independent of the lab's readers and of :mod:`renderlab.worlds.earth.wgs84`): a fixed-point geodetic
inversion written here; the pinhole projection from the manifest's numbers; the full-resolution GSHHG lon/lat of
``coastline_truth.parquet``. What is checked is the issue's promise that *the manifest's render frame lets anyone
map position AOVs back to latitude and longitude*: P → ECEF (per-frame ``render_frame``) → lat/lon lands on the
WGS-84 surface, re-projects to its own pixel centre with the manifest pose and intrinsics, and the lon/lat at the
true coastline pixels (interpolated in the AOV) equal the GSHHG lon/lat of those pixels.
"""

from __future__ import annotations

import json

import numpy as np
import OpenEXR
import pyarrow.parquet as pq
import pytest
from scipy.interpolate import RegularGridInterpolator

A, F = 6378137.0, 1.0 / 298.257223563
E2 = F * (2.0 - F)
W = 96


def _geodetic(xyz):
    """(lat, lon, h) by the fixed-point iteration lat ← atan2(z + e²N sin lat, p) (independent of Bowring's)."""
    x, y, z = xyz[..., 0], xyz[..., 1], xyz[..., 2]
    p = np.hypot(x, y)
    lat = np.arctan2(z, p)
    for _ in range(12):
        N = A / np.sqrt(1.0 - E2 * np.sin(lat) ** 2)
        lat = np.arctan2(z + E2 * N * np.sin(lat), p)
    N = A / np.sqrt(1.0 - E2 * np.sin(lat) ** 2)
    return lat, np.arctan2(y, x), p / np.cos(lat) - N


def _quat_matrix(q):
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


@pytest.fixture(scope="module")
def truthset(repo, tmp_path_factory):
    from renderlab.cli import main

    out = tmp_path_factory.mktemp("earth_set") / "set"
    rc = main(["render", str(repo / "scenes/earth_leo.toml"), "--out", str(out), "--frames", "1",
               "--set", f"camera.width={W}", "--set", f"camera.height={W}", "--set", "render.spp=1"])
    assert rc == 0
    manifest = json.loads((out / "manifest.json").read_text())
    rec = manifest["frames"][0]
    with OpenEXR.File(str(out / rec["exr"]), separate_channels=True) as exr:
        ch = {k: np.asarray(v.pixels, np.float64) for k, v in exr.channels().items()}
    return out, manifest, rec, ch


def test_position_aov_to_lat_lon_through_the_manifest(truthset):
    out, manifest, rec, ch = truthset
    assert manifest["render_frame"]["name"] == "ENU_TILE" and rec["render_frame"]["name"] == "ENU_TILE"
    rf = rec["render_frame"]                                   # one tile per frame: the frame's own render frame
    R, o = np.asarray(rf["R_ecef_from_render"]), np.asarray(rf["origin_ecef_m"])
    assert np.allclose(R.T @ R, np.eye(3), atol=1e-12)
    P = np.stack([ch["P.X"], ch["P.Y"], ch["P.Z"]], -1)
    assert np.all(np.isfinite(P)) and np.all(ch["id"] == 0), "every pixel sees the ground tile"
    ecef = P @ R.T + o
    lat, lon, h = _geodetic(ecef)
    assert np.abs(h).max() < 5.0                               # on WGS-84 (tile facets' chord sag only)
    # the manifest pose and intrinsics put every hit point back on its own pixel centre
    cam, pose = rec["camera"], rec["pose"]
    R_rc = _quat_matrix(pose["quat_render_from_cam_xyzw"])
    p_cam = (P - np.asarray(pose["position_m"])) @ R_rc        # R_rcᵀ (P − position)
    s = cam["fx"] * p_cam[..., 0] / p_cam[..., 2] + cam["cx"]
    ln = cam["fy"] * p_cam[..., 1] / p_cam[..., 2] + cam["cy"]
    L, S = np.mgrid[0:W, 0:W]
    print(f"re-projection of P AOVs through the manifest: max {max(np.abs(s - S).max(), np.abs(ln - L).max()):.4f} px")
    assert np.abs(s - S).max() < 0.02 and np.abs(ln - L).max() < 0.02
    # the manifest's spacecraft state agrees with the render-frame camera position
    sc = rec["spacecraft"]
    assert np.linalg.norm(R @ np.asarray(pose["position_m"]) + o - np.asarray(sc["r_ecef_m"])) < 0.5
    assert np.allclose(R.T @ np.asarray(rec["sun_ecef"]), rec["sun"]["direction_render"], atol=1e-12)
    # lon/lat interpolated from the AOV at the true coastline pixels = GSHHG lon/lat of those pixels
    t = pq.read_table(out / "coastline_truth.parquet")
    assert {"frame", "s", "l", "lon_deg", "lat_deg"} <= set(t.column_names)
    ts, tl = t["s"].to_numpy(), t["l"].to_numpy()
    inner = (ts > 0) & (ts < W - 1) & (tl > 0) & (tl < W - 1)
    assert inner.sum() > 200, "the frame must contain coastline"
    grid = (np.arange(W), np.arange(W))
    e_interp = np.stack([RegularGridInterpolator(grid, ecef[..., j])(np.c_[tl[inner], ts[inner]]) for j in range(3)], -1)
    la, lo, _ = _geodetic(e_interp)
    dn = (la - np.radians(t["lat_deg"].to_numpy()[inner])) * A
    de = (lo - np.radians(t["lon_deg"].to_numpy()[inner])) * A * np.cos(la)
    d = np.hypot(dn, de)
    gsd = rec["gsd_m"]
    print(f"AOV lon/lat vs GSHHG lon/lat at {inner.sum()} coastline pixels: median {np.median(d):.1f} m, "
          f"max {d.max():.1f} m (GSD {gsd:.0f} m)")
    assert d.max() < 10.0                                      # measured 1.9 m: bilinear interpolation, curved tile


def test_onboard_database_is_written_beside_the_frames(truthset):
    out, manifest, rec, _ = truthset
    info = json.loads((out / "coast_db.json").read_text())
    db = pq.read_table(out / "coast_db.parquet")
    assert {"segment_id", "lon_deg", "lat_deg", "x_ecef_m", "y_ecef_m", "z_ecef_m"} <= set(db.column_names)
    assert db.num_rows > 100
    assert info["tolerance_m"] == 150.0 and info["map_error_m_1sigma_per_axis"] == 300.0
    lon0, lat0, lon1, lat1 = info["region_bounds_lonlat_deg"]
    lon, lat = db["lon_deg"].to_numpy(), db["lat_deg"].to_numpy()
    # inside the stated region (the map error moves points by ≲ 1.5 km ≈ 0.02°)
    assert np.all((lon > lon0 - 0.05) & (lon < lon1 + 0.05) & (lat > lat0 - 0.05) & (lat < lat1 + 0.05))
    xyz = np.stack([db[c].to_numpy() for c in ("x_ecef_m", "y_ecef_m", "z_ecef_m")], -1)
    la, lo, h = _geodetic(xyz)
    assert np.abs(h).max() < 1e-3 and np.allclose(np.degrees(lo), lon, atol=1e-9)
