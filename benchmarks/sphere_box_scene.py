"""The analytic sphere-and-box scene the Mitsuba benchmarks share (benchmark helper, not part of renderlab).

``scenes/analytic_sphere_box.toml``, frame 0 of its orbit, with a square ``size`` × ``size`` camera that keeps the
scenario's horizontal view (fx, fy and the principal point's offset from the image centre scaled by size/256); the
lab's render settings for it; the same view as a plain Mitsuba scene with a ``perspective`` sensor (``mi.render``'s
own path), and how far that sensor's rays are from the lab camera's. Used by ``bench_mitsuba_llvm_vs_scalar.py``,
``bench_mitsuba_lab_vs_render.py`` and ``bench_mitsuba_gpu_vs_llvm.py``.
"""

from __future__ import annotations

import math
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

SCENE_FILE = ROOT / "scenes" / "analytic_sphere_box.toml"
REF_WIDTH = 256  # the scenario's camera width; fx, fy scale by size / REF_WIDTH


def load_inputs(size: int):
    """(scenario, scene description, frame 0 with the square camera)."""
    from renderlab.geometry.camera import CameraModel
    from renderlab.pipeline import frame_specs
    from renderlab.scenario import load_scenario
    from renderlab.worlds.analytic import build_scene

    scenario, base = load_scenario(SCENE_FILE)
    c = scenario.camera
    k = size / REF_WIDTH
    cam = CameraModel.from_dict({
        **c.model_dump(),
        "width": size, "height": size,
        "fx": c.fx * k, "fy": c.fy * k,
        # keep the principal point's offset from the image centre (pixel centres are integers)
        "cx": (size - 1) / 2 + (c.cx - (c.width - 1) / 2) * k,
        "cy": (size - 1) / 2 + (c.cy - (c.height - 1) / 2) * k,
    })
    frame = replace(frame_specs(scenario)[0], camera=cam)
    scene = build_scene(scenario.world, base)
    if any(b.albedo_map is not None for b in scene.bodies):
        raise SystemExit("benchmark expects no albedo maps in the analytic scene")
    return scenario, scene, frame


def band_frame(frame, band: tuple[int, int]):
    """The same frame restricted to the image rows ``band = (first row, rows)``."""
    r0, rows = band
    cam = frame.camera
    return replace(frame, camera=replace(cam, height=rows, cy=cam.cy - r0))


def representative_band(hit: np.ndarray, rows: int) -> tuple[int, int]:
    """The band of ``rows`` consecutive rows whose fraction of pixels that hit a body is closest to the
    full frame's (rays that miss everything are much cheaper than hits); ties go to the centre."""
    H = hit.shape[0]
    per_row = hit.mean(axis=1)
    target = per_row.mean()
    sums = np.convolve(per_row, np.ones(rows), "valid") / rows  # mean hit fraction of band r0..r0+rows-1
    r0s = np.arange(len(sums))
    best = min(r0s, key=lambda r0: (round(abs(sums[r0] - target), 4), abs(r0 - (H - rows) / 2)))
    return int(best), rows


def lab_settings(scenario, variant: str, spp: int, pixel_filter: str):
    from renderlab.render.scene import RenderSettings

    r = scenario.render
    return RenderSettings(variant=variant, spp=spp, max_depth=r.max_depth, pixel_filter=pixel_filter,
                          near_clip_m=r.near_clip_m, far_clip_m=r.far_clip_m)


def set_variant(variant: str):
    """Select ``variant`` (renderlab's init: LLVM 19) and refuse a silent scalar fallback."""
    from renderlab.render.variant import init_mitsuba

    mi = init_mitsuba(variant)
    if mi.variant() != variant:
        raise SystemExit(f"Mitsuba variant {variant} is not usable here (got {mi.variant()}); "
                         "an LLVM vs scalar comparison is meaningless. Run ./setup.sh (libllvm19).")
    return mi


def native_scene(mi, scenario, scene, frame, spp: int, bsdf: str, crop: tuple | None = None,
                 pixel_format: str = "rgb"):
    """A plain Mitsuba scene (perspective sensor) showing the frame's view of ``scene``.

    ``crop = (first row, rows)`` renders only those rows of the film (``hdrfilm`` crop window);
    ``pixel_format`` of the film (``luminance`` for a mono variant)."""
    from renderlab.render.mitsuba_backend import _transform4
    from renderlab.render.mitsuba_bsdf import bsdf_dict, register_bsdfs

    register_bsdfs(mi)
    T = mi.ScalarTransform4f
    cam, pose = frame.camera, frame.pose
    W, H = cam.width, cam.height
    # Mitsuba camera axes: +x left, +y up, +z forward; the lab's: +x right, +y down, +z forward.
    R = pose.rotation.as_matrix() @ np.diag([-1.0, -1.0, 1.0])
    to_world = np.eye(4)
    to_world[:3, :3], to_world[:3, 3] = R, pose.position_m
    s = np.asarray(frame.sun.direction_render, float)
    s = s / np.linalg.norm(s)
    up = [0.0, 0.0, 1.0] if abs(s[2]) < 0.9 else [1.0, 0.0, 0.0]
    desc = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": scenario.render.max_depth, "hide_emitters": True},
        "sun": {"type": "directional", "irradiance": float(frame.sun.irradiance_w_m2),
                "to_world": T().look_at(origin=[0, 0, 0], target=(-s).tolist(), up=up)},
        "sensor": {
            "type": "perspective",
            "fov_axis": "x",
            # full image width (pixel edges -0.5 .. W-0.5) from fx; Mitsuba has square pixels, so fy = fx
            "fov": math.degrees(2 * math.atan(W / 2 / cam.fx)),
            # principal point relative to the film centre, in units of the film size
            "principal_point_offset_x": (W / 2 - (cam.cx + 0.5)) / W,
            "principal_point_offset_y": (H / 2 - (cam.cy + 0.5)) / H,
            "near_clip": scenario.render.near_clip_m,
            "far_clip": scenario.render.far_clip_m,
            "to_world": T(to_world.tolist()),
            "sampler": {"type": "independent", "sample_count": spp},
            "film": {"type": "hdrfilm", "width": W, "height": H, "rfilter": {"type": "box"},
                     "pixel_format": pixel_format},
        },
    }
    if crop is not None:
        desc["sensor"]["film"].update(crop_offset_x=0, crop_offset_y=int(crop[0]), crop_width=W,
                                      crop_height=int(crop[1]))
    for body in scene.bodies:
        R_b, c = body.R_render_from_body, body.center_m
        if body.shape == "sphere":
            d = {"type": "sphere", "to_world": T(_transform4(R_b, c, body.radius_m))}
        elif body.shape == "box":
            d = {"type": "cube", "to_world": T(_transform4(R_b, c, np.asarray(body.size_m) / 2))}
        elif body.shape == "plane":
            sx, sy = body.size_m
            d = {"type": "rectangle", "to_world": T(_transform4(R_b, c, [sx / 2, sy / 2, 1.0]))}
        else:
            raise SystemExit(f"benchmark: unexpected shape {body.shape}")
        if bsdf == "lab":
            d["bsdf"] = bsdf_dict(body.law, float(body.albedo))
        else:
            d["bsdf"] = {"type": "diffuse", "reflectance": float(body.albedo)}
        desc[f"body{body.body_id}"] = d
    return mi.load_dict(desc, optimize=False)


def sensor_ray_error_px(mi, nscene, frame) -> float:
    """Largest angle (in pixels of fx) between the native sensor's and the lab camera's centre rays."""
    cam = frame.camera
    W, H = cam.width, cam.height
    sl = np.array([[0, 0], [W - 1, 0], [0, H - 1], [W - 1, H - 1], [cam.cx, cam.cy],
                   [W // 2, H // 2], [W // 4, 3 * H // 4]], float)
    d_lab = cam.unproject(sl) @ frame.pose.rotation.as_matrix().T
    d_lab /= np.linalg.norm(d_lab, axis=1, keepdims=True)
    sensor = nscene.sensors()[0]
    worst = 0.0
    for (s, l), dl in zip(sl, d_lab):
        ray, _ = sensor.sample_ray(0.0, 0.5, mi.Point2f((s + 0.5) / W, (l + 0.5) / H), mi.Point2f(0.5, 0.5))
        dn = np.array([float(v) for v in np.ravel(np.array(ray.d))])
        dn /= np.linalg.norm(dn)
        worst = max(worst, math.acos(min(1.0, float(dn @ dl))))
    return worst * cam.fx
