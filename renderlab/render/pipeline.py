"""Scenario → truth set: world, camera path, renderer, sensor, files.

Seeds: the scenario's ``render.seed`` (or ``--seed``) roots a ``SeedSequence``; frame k uses its
k-th spawned child, split again into the renderer's sample pattern and the sensor noise. The same
seed therefore gives bit-identical EXR and DN files, and any frame can be re-rendered alone.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from renderlab.dynamics.camera_paths import camera_path
from renderlab.errors import UserError
from renderlab.geometry.camera import CameraModel
from renderlab.geometry.rotations import quat_xyzw
from renderlab.render.scene import FrameSpec, RenderSettings, SunSpec
from renderlab.scenario import Scenario
from renderlab.sensor import SensorOptions, expose, exposure_for_peak, with_exposure
from renderlab.truthset import TruthSetWriter
from renderlab.worlds.analytic import build_scene


def frame_specs(scenario: Scenario) -> list[FrameSpec]:
    """Camera, pose and sun of every frame of the scenario."""
    cam_cfg = scenario.camera.model_dump()
    camera = CameraModel.from_dict(cam_cfg)
    s = np.asarray(scenario.sun.direction, float)
    sun = SunSpec(direction_render=s / np.linalg.norm(s), irradiance_w_m2=scenario.sun.irradiance_w_m2)
    return [FrameSpec(index=k, pose=p, camera=camera, sun=sun) for k, p in enumerate(camera_path(scenario.trajectory))]


def make_backend(scenario: Scenario, scene, renderer: str):
    settings = RenderSettings(
        variant=scenario.render.variant,
        spp=scenario.render.spp,
        max_depth=scenario.render.max_depth,
        pixel_filter=scenario.render.pixel_filter,
        near_clip_m=scenario.render.near_clip_m,
        far_clip_m=scenario.render.far_clip_m,
    )
    if renderer == "mitsuba":
        from renderlab.render.mitsuba_backend import MitsubaBackend

        try:
            return MitsubaBackend(scene, settings)
        except RuntimeError as exc:  # Mitsuba reports an unreadable mesh as 'At dictionary node "bodyK": ...'
            for body in scene.bodies:
                if body.mesh_path is not None and f'"body{body.body_id}"' in str(exc):
                    detail = str(exc).rsplit("] ", 1)[-1]
                    raise UserError(f"world.bodies.{body.body_id}.file: cannot load mesh "
                                    f"{body.mesh_path.name}: {detail}") from None
            raise
    raise UserError(f"renderer '{renderer}' is not available yet (only 'mitsuba' is)")


def render_truthset(
    scenario: Scenario,
    base_dir: Path,
    out_dir: Path,
    *,
    frames: int | None = None,
    seed: int | None = None,
    renderer: str | None = None,
    progress: bool = True,
    overwrite: bool = False,
) -> Path:
    """Render a scenario into a truth set folder (written atomically) and return its path."""
    from tqdm import tqdm

    seed = scenario.render.seed if seed is None else int(seed)
    if seed < 0:
        raise UserError(f"--seed must be a non-negative integer, got {seed}")
    if seed != scenario.render.seed:  # the manifest's scenario records the seed actually used
        scenario = scenario.model_copy(update={"render": scenario.render.model_copy(update={"seed": seed})})
    renderer = renderer or scenario.render.renderer
    specs = frame_specs(scenario)
    if frames is not None:
        if frames < 1:
            raise UserError(f"--frames must be at least 1, got {frames}")
        specs = specs[:frames]
    scene = build_scene(scenario.world, base_dir)
    head = {"scenario": scenario.to_dict(), "render_frame": scene.render_frame, "seed": seed}
    TruthSetWriter(out_dir, head, overwrite=overwrite)  # refuses a bad output folder before the slow start
    backend = make_backend(scenario, scene, renderer)
    writer = TruthSetWriter(
        out_dir,
        {**head, "renderer": {"name": backend.name, "version": backend.version, "variant": backend.variant}},
        overwrite=overwrite,
    )
    opts = SensorOptions(**scenario.sensor.options_dict())
    children = np.random.SeedSequence(seed).spawn(len(specs))
    with writer:
        for spec, child in tqdm(list(zip(specs, children)), desc="render", unit="frame", disable=not progress):
            render_ss, sensor_ss = child.spawn(2)
            out = backend.render(spec, seed=int(render_ss.generate_state(1)[0]))
            lum = out.radiance if out.radiance.ndim == 2 else out.radiance.mean(-1)  # mono sensor
            if spec.index == specs[0].index and scenario.sensor.auto_exposure:
                t_exp = exposure_for_peak(lum, opts, fraction=scenario.sensor.auto_exposure_fraction)
                opts = with_exposure(opts, t_exp)
            sensor = expose(lum, opts, np.random.default_rng(sensor_ss))
            meta = {
                "camera": spec.camera.to_dict(),
                "pose": {
                    "position_m": [float(v) for v in spec.pose.position_m],
                    "quat_render_from_cam_xyzw": [float(v) for v in quat_xyzw(spec.pose.rotation)],
                },
                "sun": spec.sun.to_dict(),
                "bodies": {b.name: b.state() for b in scene.bodies},
                "sensor": {"exposure_s": float(opts.exposure_s), "bits": int(opts.bits),
                           "gain_e_per_dn": float(opts.gain_e_per_dn), "bias_dn": float(opts.bias_dn)},
            }
            writer.add_frame(spec.index, float(spec.pose.time_s), out.exr_channels(), sensor.dn, meta)
    return Path(out_dir)
