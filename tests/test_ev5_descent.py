"""EV5 descent truth sets rendered by the real pipeline and Mitsuba backend: landmark truth against the
position AOV and an independent line-of-sight oracle, the descent geometry, determinism."""

from __future__ import annotations

import copy
import json

import numpy as np
import pytest
from scipy.interpolate import RegularGridInterpolator
from scipy.spatial.transform import Rotation

from renderlab.files.imageio import read_exr

SCENARIO = {
    "name": "ev5_test",
    "world": {
        "kind": "ev5", "seed": 5, "facet_m": 4.0, "law": "hapke",
        "site": {"extent_m": 30.0, "cell_m": 0.05, "taper_m": 1.0, "crater_max_m": 3.0, "boulder_min_m": 0.3},
        "landmarks": [{"name": "regional", "count": 8, "spacing_m": 0.2, "size": 15, "radius_m": 6.0},
                      {"name": "site", "count": 10, "spacing_m": 0.1, "size": 15, "radius_m": 2.5}],
    },
    "trajectory": {"kind": "ev5_descent", "altitudes_m": [100.0, 20.0]},
    "camera": {"width": 128, "height": 128, "fx": 610.0, "fy": 610.0, "cx": 63.5, "cy": 63.5},
    "render": {"spp": 2, "seed": 3, "near_clip_m": 0.01},
}


def _render(out):
    from renderlab.pipeline import render_truthset
    from renderlab.scenario import scenario_from_dict

    return render_truthset(scenario_from_dict(copy.deepcopy(SCENARIO)), ".", out, progress=False)


@pytest.fixture(scope="module")
def truthset(tmp_path_factory):
    return _render(tmp_path_factory.mktemp("ev5") / "set")


def _table(path, name):
    import pyarrow.parquet as pq

    return pq.read_table(str(path / f"{name}.parquet")).to_pydict()


def _project(frame, c):
    """Independent pinhole projection of body (= render) points from the manifest's pose and K."""
    cam, pose = frame["camera"], frame["pose"]
    R = Rotation.from_quat(pose["quat_render_from_cam_xyzw"]).as_matrix()
    p = (c - np.asarray(pose["position_m"])) @ R
    x, y = p[:, 0] / p[:, 2], p[:, 1] / p[:, 2]
    return np.column_stack([cam["fx"] * x + cam["skew"] * y + cam["cx"], cam["fy"] * y + cam["cy"]]), p[:, 2]


def _aov_at(P, s, l):
    """The position AOV (pixel-centre hit points) bilinearly interpolated at sub-pixel (s, l), clamped to the image."""
    H, W = P.shape[:2]
    s, l = min(max(s, 0.0), W - 1.0), min(max(l, 0.0), H - 1.0)
    i, j = min(int(s), W - 2), min(int(l), H - 2)
    fs, fl = s - i, l - j
    return ((1 - fl) * ((1 - fs) * P[j, i] + fs * P[j, i + 1]) + fl * ((1 - fs) * P[j + 1, i] + fs * P[j + 1, i + 1]))


def test_visible_landmarks_sit_on_the_position_aov(truthset):
    """Every visible landmark in both frames: the rendered position AOV at its truth (s, l) lies within one
    maplet cell of the landmark centre; (s, l) match an independent projection; in-view flags match the
    image bounds; ``aov_offset_m`` is the offset at the nearest pixel centre, and that too is within one
    cell where the pixel is no larger than a cell (GSD ≤ spacing)."""
    from renderlab.worlds.ev5.catalog import read_catalog

    manifest = json.loads((truthset / "manifest.json").read_text())
    maplets = {m.landmark_id: m for m in read_catalog(truthset)}
    lt = _table(truthset, "landmark_truth")
    checked = coarse = 0
    for k, frame in enumerate(manifest["frames"]):
        exr = read_exr(truthset / frame["exr"])
        P = np.stack([exr["P.X"], exr["P.Y"], exr["P.Z"]], -1).astype(np.float64)
        rows = [i for i, f in enumerate(lt["frame"]) if f == frame["index"]]
        assert len(rows) == len(maplets)
        ids = [lt["landmark_id"][i] for i in rows]
        C = np.array([maplets[i].center_m for i in ids])
        sl, z = _project(frame, C)
        W, H = frame["camera"]["width"], frame["camera"]["height"]
        inside = (z > 0) & (sl[:, 0] >= -0.5) & (sl[:, 0] < W - 0.5) & (sl[:, 1] >= -0.5) & (sl[:, 1] < H - 0.5)
        for r, lid, (s, l), ins in zip(rows, ids, sl, inside):
            assert lt["in_view"][r] == bool(ins)
            if not ins:
                continue
            assert abs(lt["s"][r] - s) < 1e-6 and abs(lt["l"][r] - l) < 1e-6
            if lt["visible"][r]:
                spacing = maplets[lid].spacing_m
                at_sl = np.linalg.norm(_aov_at(P, s, l) - maplets[lid].center_m)
                assert at_sl <= spacing, (k, lid, at_sl / spacing, lt["gsd_ratio"][r])
                nearest = np.linalg.norm(P[int(round(l)), int(round(s))] - maplets[lid].center_m)
                assert abs(nearest - lt["aov_offset_m"][r]) < 1e-4
                if lt["gsd_ratio"][r] <= 1.0:
                    assert nearest <= spacing, (k, lid, nearest)
                checked += 1
                coarse += lt["gsd_ratio"][r] > 1.0
    assert checked >= 20 and coarse >= 5  # both frames, landmarks finer and coarser than the pixels


def test_descent_geometry_and_truth_angles(truthset):
    """Frames at the requested altitudes above the site; spin-matched frame on the site normal; the
    phase angle at the site centre of the spin-matched frame equals trajectory.phase_deg for a camera
    on the normal; GSD ratios follow range / fx / spacing."""
    manifest = json.loads((truthset / "manifest.json").read_text())
    site = json.loads((truthset / "site.json").read_text())
    o, R = np.array(site["origin_m"]), np.array(site["R_body_from_site"])
    assert manifest["render_frame"]["name"] == "EV5_FIXED"
    f0, f1 = manifest["frames"]
    assert f0["ev5"]["altitude_m"] == pytest.approx(100.0, abs=1e-3)
    assert not f0["ev5"]["spin_matched"] and f1["ev5"]["spin_matched"]
    p1 = np.array(f1["pose"]["position_m"])
    assert np.allclose(p1, o + 20.0 * R[:, 2], atol=1e-6)
    # above the spin match: same distance from the body centre as the inertial line, rotated about +z
    p0 = np.array(f0["pose"]["position_m"])
    assert np.linalg.norm(p0) == pytest.approx(np.linalg.norm(o + 100.0 * R[:, 2]), rel=1e-9)
    assert p0[2] == pytest.approx((o + 100.0 * R[:, 2])[2], abs=1e-6)
    # sun: unit, fixed in inertial space → same ecliptic direction in both frames
    assert np.allclose(f0["ev5"]["sun_direction_eclip"], f1["ev5"]["sun_direction_eclip"], atol=1e-9)
    lt = _table(truthset, "landmark_truth")
    cat = _table(truthset, "landmarks")
    frames = {f["index"]: f for f in manifest["frames"]}
    for i in range(len(lt["frame"])):
        assert lt["gsd_ratio"][i] == pytest.approx(lt["range_m"][i] / 610.0 / (0.2 if lt["tier"][i] == "regional" else 0.1))
        assert 0 <= lt["shadow_fraction"][i] <= 1
        # incidence, emission, phase (Retina eqs. 6-8) from the catalog's maplet frame and the manifest
        k = cat["landmark_id"].index(lt["landmark_id"][i])
        c = np.array([cat[f"center_{a}_m"][k] for a in "xyz"])
        n = Rotation.from_quat([cat[f"q_body_from_maplet_{a}"][k] for a in "xyzw"]).as_matrix()[:, 2]
        f = frames[lt["frame"][i]]
        sun = np.asarray(f["sun"]["direction_render"])
        to_cam = np.asarray(f["pose"]["position_m"]) - c
        def ang(a, b):
            return np.degrees(np.arccos(np.clip(a @ b / np.linalg.norm(a) / np.linalg.norm(b), -1, 1)))

        assert lt["range_m"][i] == pytest.approx(np.linalg.norm(to_cam), rel=1e-12)
        assert lt["incidence_deg"][i] == pytest.approx(ang(n, sun), abs=1e-6)
        assert lt["emission_deg"][i] == pytest.approx(ang(n, to_cam), abs=1e-6)
        assert lt["phase_deg"][i] == pytest.approx(ang(sun, to_cam), abs=1e-6)
    # turned back to the spin-match time t_m = 900 + 600 s (body spin ω = 2π / 3.725 h about +z), the sun
    # makes the default phase_deg = 30° with the site normal, at azimuth 60° from east toward north
    omega = 2 * np.pi / (3.725 * 3600.0)
    for f in (f0, f1):
        s_m = Rotation.from_rotvec([0, 0, omega * (f["time_s"] - 1500.0)]).apply(f["sun"]["direction_render"])
        assert np.degrees(np.arccos(s_m @ R[:, 2])) == pytest.approx(30.0, abs=1e-6)
        assert np.degrees(np.arctan2(s_m @ R[:, 1], s_m @ R[:, 0])) == pytest.approx(60.0, abs=1e-6)
    assert f1["time_s"] == pytest.approx(1500.0 + (50.0 - 20.0) / 0.1)


def test_occluded_landmarks_flagged_like_an_independent_line_of_sight_oracle():
    """A low, grazing view across the target boulder: landmarks behind it are flagged occluded exactly
    where a ray march against the site DEM (scipy bilinear interpolation) finds the line of sight blocked."""
    from renderlab.dynamics.camera_paths import CameraPose
    from renderlab.geometry.rotations import look_at
    from renderlab.pipeline import make_backend
    from renderlab.render.scene import FrameSpec
    from renderlab.scenario import scenario_from_dict
    from renderlab.worlds.ev5 import make_plan

    sc = scenario_from_dict(copy.deepcopy(SCENARIO) | {"camera": {"width": 96, "height": 96, "fx": 120.0,
                                                                 "fy": 120.0, "cx": 47.5, "cy": 47.5}})
    plan = make_plan(sc, ".")
    site = plan.model.site
    eye = site.to_body([-9.0, 0.3, float(site.height_at(-9.0, 0.3)) + 0.6])
    target = site.to_body([2.0, 0.0, float(site.height_at(2.0, 0.0))])
    base = plan.frames[0]
    spec = FrameSpec(index=0, pose=CameraPose(0.0, eye, look_at(eye, target, site.R_body_from_site[:, 2])),
                     camera=base.camera, sun=base.sun)
    rendered = make_backend(sc, plan.static_scene, "mitsuba").render(spec, seed=1)
    rows = plan.frame_rows(spec, rendered)["landmark_truth"]
    t = np.linspace(site.x0_m, site.x0_m + site.extent_m, site.n)
    dem = RegularGridInterpolator((t, t), site.heights_m)  # (y, x) order
    e_s = site.to_site(eye)
    n_occ = n_vis = 0
    for row, m in zip(rows, plan.model.maplets):
        if not row["in_view"]:
            continue
        c_s = site.to_site(m.center_m)
        tol = max(m.spacing_m, 3 * row["gsd_m"])
        f = np.linspace(0, 1 - tol / np.linalg.norm(c_s - e_s), 4000)
        q = e_s + f[:, None] * (c_s - e_s)
        excess = dem(np.column_stack([q[:, 1], q[:, 0]])) - q[:, 2]
        if abs(excess.max()) < 0.02:
            continue  # grazing: neither oracle is decisive
        blocked = excess.max() > 0
        assert row["occluded"] == blocked, (m.landmark_id, excess.max())
        n_occ += blocked
        n_vis += not blocked
    assert n_occ >= 1 and n_vis >= 1


def test_same_seed_same_truth_set(truthset, tmp_path):
    """Same scenario and seeds → byte-identical frames, catalog, maplets and tables."""
    again = _render(tmp_path / "again")
    files = sorted(p.relative_to(truthset) for p in truthset.rglob("*") if p.is_file())
    assert files == sorted(p.relative_to(again) for p in again.rglob("*") if p.is_file())
    assert any(str(f).startswith("maplets/") for f in files)
    assert {"contact_sheet.png", "landmarks.parquet", "landmark_truth.parquet", "site.json"} <= {str(f) for f in files}
    for f in files:
        assert (truthset / f).read_bytes() == (again / f).read_bytes(), f


TINY_SETS = ["world.facet_m=4.0", "world.site.extent_m=30.0", "world.site.cell_m=0.05", "world.site.taper_m=1.0",
             "world.site.crater_max_m=3.0", "world.site.boulder_min_m=0.3",
             'world.landmarks=[{name="regional", count=6, spacing_m=0.2, size=15, radius_m=6.0}, '
             '{name="site", count=6, spacing_m=0.1, size=15, radius_m=2.5}]',
             "camera.width=64", "camera.height=64", "camera.fx=304.5", "camera.fy=304.5", "camera.cx=31.5",
             "camera.cy=31.5", "render.spp=2"]


def _cli(*args):
    import subprocess
    import sys

    return subprocess.run([sys.executable, "-m", "renderlab", *args], capture_output=True, text=True, timeout=600)


def test_cli_renders_the_scene_file_with_catalog_truth_table_and_contact_sheet(tmp_path):
    """`renderlab render scenes/ev5_descent.toml --out DIR --frames 2` (shrunk by --set): a truth set with the
    catalog, one maplet per landmark, the landmark truth table and a contact-sheet PNG of the frames; a bad
    key exits 2 with one `renderlab: error:` line and writes nothing."""
    from PIL import Image

    out = tmp_path / "set"
    sets = [a for s in TINY_SETS for a in ("--set", s)]
    res = _cli("render", "scenes/ev5_descent.toml", "--out", str(out), "--frames", "2", *sets)
    assert res.returncode == 0, res.stderr
    manifest = json.loads((out / "manifest.json").read_text())
    assert len(manifest["frames"]) == 2 and manifest["render_frame"]["name"] == "EV5_FIXED"
    assert [round(f["ev5"]["altitude_m"], 3) for f in manifest["frames"]] == \
        pytest.approx(list(np.geomspace(1000.0, 5.0, 12)[:2]), abs=1e-3)
    cat = _table(out, "landmarks")
    assert len(cat["landmark_id"]) == 12 and sorted(set(cat["tier"])) == ["regional", "site"]
    assert sorted(p.name for p in (out / "maplets").iterdir()) == [f"{i:06d}.exr" for i in cat["landmark_id"]]
    lt = _table(out, "landmark_truth")
    for col in ("frame", "landmark_id", "s", "l", "visible", "occluded", "incidence_deg", "emission_deg",
                "phase_deg", "shadow_fraction", "gsd_ratio"):
        assert len(lt[col]) == 24, col
    sheet = np.asarray(Image.open(out / "contact_sheet.png").convert("L"), float)
    assert sheet.shape[0] > 100 and sheet.std() > 1.0  # an image with content, not a blank page

    bad = _cli("render", "scenes/ev5_descent.toml", "--out", str(tmp_path / "bad"), "--frames", "2", *sets,
               "--set", "world.site.target_boulder_m=5.0")
    assert bad.returncode == 2
    lines = bad.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("renderlab: error:") and "target_boulder_m" in lines[0], bad.stderr
    assert not (tmp_path / "bad").exists()
