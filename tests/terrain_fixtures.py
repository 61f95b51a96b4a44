"""The small test terrain the Retina, SPC and measurement tests share (test helper, not part of renderlab): a DEM of
hills, craters, boulders and albedo texture as an in-memory ``trimesh`` body, coarser maplets with height errors, a
camera and Sun, Mitsuba renders to DN, the module-scoped two-frame truth set ``truthset`` (a fixture) and a user's
own images + a-priori file made from it (:func:`write_inputs`)."""

from __future__ import annotations

import json

import numpy as np
import pyarrow as pa
import pytest

from renderlab.geometry.camera import CameraModel
from renderlab.geometry.maplet import Maplet
from renderlab.geometry.rotations import look_at

SPACING_TRUTH = 0.05
HALF = 6.0
LANDMARKS = [(-2.6, -2.0), (2.4, -1.6), (0.2, 2.6)]


def terrain_dem(seed: int = 7):
    """(x, y, Z, albedo) of a 12 m × 12 m DEM at 5 cm: hills, craters with rims, boulders, texture."""
    rng = np.random.default_rng(seed)
    x = np.arange(-HALF, HALF + 1e-9, SPACING_TRUTH)
    X, Y = np.meshgrid(x, x)
    Z = np.zeros_like(X)
    for _ in range(6):  # hills
        cx, cy, s, a = rng.uniform(-HALF, HALF), rng.uniform(-HALF, HALF), rng.uniform(1.5, 3.0), rng.uniform(-0.5, 0.6)
        Z += a * np.exp(-((X - cx) ** 2 + (Y - cy) ** 2) / (2 * s * s))
    for _ in range(10):  # craters: bowl + raised rim
        cx, cy, R = rng.uniform(-HALF, HALF), rng.uniform(-HALF, HALF), rng.uniform(0.4, 1.2)
        r = np.hypot(X - cx, Y - cy) / R
        Z += np.where(r < 1, 0.35 * R * (r * r - 1), 0.0) + 0.08 * R * np.exp(-((r - 1) / 0.25) ** 2)
    for _ in range(60):  # boulders
        cx, cy, R = rng.uniform(-HALF, HALF), rng.uniform(-HALF, HALF), rng.uniform(0.1, 0.35)
        Z += 0.8 * R * np.exp(-((X - cx) ** 2 + (Y - cy) ** 2) / (2 * (0.6 * R) ** 2))
    from scipy.ndimage import gaussian_filter

    tex = gaussian_filter(rng.normal(size=X.shape), 4.0)
    albedo = 1.0 + 0.25 * tex / tex.std()
    return x, X, Y, Z, np.clip(albedo, 0.3, 2.0)


def terrain_body(dem):
    from renderlab.photometry import make_law
    from renderlab.render.scene import BodySpec

    x, X, Y, Z, alb = dem
    n = len(x)
    V = np.column_stack([X.ravel(), Y.ravel(), Z.ravel()])
    j, i = np.meshgrid(np.arange(n - 1), np.arange(n - 1), indexing="ij")
    a, b, c, d = (j * n + i).ravel(), (j * n + i + 1).ravel(), ((j + 1) * n + i + 1).ravel(), ((j + 1) * n + i).ravel()
    Fc = np.concatenate([np.stack([a, b, c], -1), np.stack([a, c, d], -1)])
    return BodySpec(name="terrain", body_id=0, shape="trimesh", center_m=np.zeros(3), R_render_from_body=np.eye(3),
                    law=make_law("mcewen"), albedo=0.1, vertices=V, faces=Fc, vertex_albedo=alb.ravel())


def make_maplets(dem, spacing: float = 0.1, n: int = 49, height_noise_m: float = 0.01, seed: int = 3):
    """Coarser maplets sampled from the DEM (every 2nd point), with smoothing and height noise."""
    from scipy.interpolate import RegularGridInterpolator
    from scipy.ndimage import gaussian_filter

    x, X, Y, Z, alb = dem
    rng = np.random.default_rng(seed)
    fz = RegularGridInterpolator((x, x), Z)
    fa = RegularGridInterpolator((x, x), alb)
    t = (np.arange(n) - (n - 1) / 2) * spacing
    out = []
    for k, (cx, cy) in enumerate(LANDMARKS):
        cz = float(fz([cy, cx])[0])
        gy, gx = np.meshgrid(t + cy, t + cx, indexing="ij")
        pts = np.column_stack([gy.ravel(), gx.ravel()])
        h = gaussian_filter(fz(pts).reshape(n, n), 0.5) - cz + rng.normal(0, height_noise_m, (n, n))
        a = fa(pts).reshape(n, n)
        out.append(Maplet(k, np.array([cx, cy, cz]), np.eye(3), spacing, h, a / a.mean()))
    return out


CAMERA = CameraModel.from_dict({"width": 128, "height": 128, "fx": 160.0, "fy": 160.0, "cx": 63.5, "cy": 63.5})
CAM_POS = np.array([1.5, -4.0, 13.0])
SUN = np.array([0.55, 0.35, 0.40]) / np.linalg.norm([0.55, 0.35, 0.40])


def true_pose():
    from estimators.retina import CameraPoseEstimate

    return CameraPoseEstimate(look_at(CAM_POS, np.array([0.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])).as_matrix(), CAM_POS)


def render_dn(dem, pose, camera=CAMERA, seed: int = 0, spp: int = 4):
    """Render the terrain with Mitsuba and expose it → (radiance, dn)."""
    from scipy.spatial.transform import Rotation

    from renderlab.dynamics.camera_paths import CameraPose
    from renderlab.render.mitsuba_backend import MitsubaBackend
    from renderlab.render.scene import FrameSpec, RenderSettings, SceneDescription, SunSpec
    from renderlab.sensor.model import SensorOptions, expose, exposure_for_peak, with_exposure

    be = MitsubaBackend(SceneDescription(bodies=[terrain_body(dem)]), RenderSettings(spp=spp))
    cp = CameraPose(0.0, pose.position_m, Rotation.from_matrix(pose.R_body_from_cam))
    out = be.render(FrameSpec(0, cp, camera, SunSpec(SUN, 1361.0)), seed=seed)
    opts = SensorOptions()
    opts = with_exposure(opts, exposure_for_peak(out.radiance, opts))
    dn = expose(out.radiance, opts, np.random.default_rng(seed)).dn
    return out, dn



@pytest.fixture(scope="module")
def truthset(tmp_path_factory):
    from scipy.spatial.transform import Rotation

    from estimators.retina import CameraPoseEstimate, project_point
    from renderlab.files.truthset import TruthSetWriter

    dem = terrain_dem()
    maplets = make_maplets(dem)
    p0 = true_pose()
    p1 = CameraPoseEstimate(p0.R_body_from_cam @ Rotation.from_rotvec([0.01, -0.02, 0.05]).as_matrix(),
                            p0.position_m + np.array([0.3, 0.2, -0.5]))
    out = tmp_path_factory.mktemp("ts") / "set"
    rows = []
    with TruthSetWriter(out, {"renderer": {"name": "mitsuba"}}) as w:
        for k, pose in enumerate((p0, p1)):
            rf, dn = render_dn(dem, pose, seed=k)
            meta = {"camera": CAMERA.to_dict(),
                    "pose": {"position_m": pose.position_m.tolist(),
                             "quat_render_from_cam_xyzw": Rotation.from_matrix(pose.R_body_from_cam).as_quat().tolist()},
                    "sun": {"direction_render": SUN.tolist(), "irradiance_w_m2": 1361.0},
                    "sensor": {"bits": 10, "bias_dn": 16.0, "gain_e_per_dn": 20.0}}
            w.add_frame(k, float(k), rf.exr_channels(), dn, meta)
            for m in maplets:
                s, l = project_point(CAMERA, pose, m.center_m)
                rows.append({"frame": k, "landmark_id": m.landmark_id, "s": float(s), "l": float(l), "visible": True,
                             "occluded": bool(k == 1 and m.landmark_id == 2), "incidence_deg": 40.0,
                             "emission_deg": 20.0, "phase_deg": 50.0, "shadow_fraction": 0.05, "gsd_ratio": 0.9})
        w.add_table("landmark_truth", pa.Table.from_pylist(rows))
        try:
            from renderlab.worlds.ev5.catalog import write_catalog
        except ImportError:  # the EV5 world is not there yet: the CLI tests that need a catalog skip
            pass
        else:
            write_catalog(w, maplets)
    return out, maplets



def write_inputs(tmp_path, ts_path, shift=(0, 0), fmt="png", name="img"):
    import cv2

    from renderlab.files.truthset import TruthSet

    ts = TruthSet.open(ts_path)
    dn = ts.load(0).dn.astype(np.uint16)
    M = np.array([[1.0, 0.0, shift[0]], [0.0, 1.0, shift[1]]])
    img = cv2.warpAffine(dn, M, (dn.shape[1], dn.shape[0]), flags=cv2.INTER_NEAREST, borderMode=cv2.BORDER_REPLICATE)
    if fmt == "png":
        assert cv2.imwrite(str(tmp_path / f"{name}.png"), img)
        fname = f"{name}.png"
    else:
        from astropy.io import fits

        fits.PrimaryHDU(img.astype(np.int32)).writeto(tmp_path / f"{name}.fits")
        fname = f"{name}.fits"
    rec = ts.frames[0]
    apriori = {"camera": rec["camera"], "bits": 10, "frame": "BODY",
               "images": [{"file": fname, "epoch_utc": "2026-12-02T00:00:00Z",
                           "position_m": rec["pose"]["position_m"],
                           "quat_body_from_cam_xyzw": rec["pose"]["quat_render_from_cam_xyzw"],
                           "sun_direction_body": rec["sun"]["direction_render"],
                           "position_sigma_m": [0.2, 0.2, 0.2], "attitude_sigma_deg": [0.05, 0.05, 0.05]}]}
    path = tmp_path / f"{name}_apriori.json"
    path.write_text(json.dumps(apriori))
    return path


