"""The planet world: one resolved body — the Moon, Mars, the Earth without clouds, 2008 EV5 from afar, or any sphere or
triaxial ellipsoid — for centre-finding and limb/horizon navigation (cruise, approach, orbit).

* Body (:mod:`.body`): the renderer's sphere, a fine ellipsoid mesh with exact normals, or the EV5 shape; one
  photometric law (``lambert``, ``lommel_seeliger``, ``hapke``, ``mcewen``: :mod:`renderlab.photometry`); presets in
  :mod:`.config`. The render frame ``PLANET_FIXED`` has the body's centre at its origin (the EV5 shape: its mesh
  origin) and the body axes turned by ``world.rotation_deg``; the body does not spin.
* Sun: ``[sun] direction`` (render frame, toward the sun) and irradiance.
* Camera: the world's own ``planet_approach`` path (range and phase angle per frame, :mod:`.path`), the lab's ``line``
  and ``orbit`` paths, or the user's file trajectories (``table``, ``ccsds``, ``spice``) in ``PLANET_FIXED``
  (:func:`renderlab.worlds.base.frame_specs`), their attitude from the files or ``attitude = "look_at"``.
* Render origin: the body centre when float32 allows it, else where the camera looks (:func:`.path.render_origin`).
* Truth: ``centre_truth.parquet`` (:mod:`.truth`): projected centre, true limb conic (centre, semi-axes, angle), range,
  line of sight, phase, limb cone; per frame the manifest's ``planet`` entry names the preset, the truth ellipsoid and
  the render origin.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from renderlab.worlds.base import WorldPlan

RENDER_FRAME = {"name": "PLANET_FIXED"}


@dataclass
class PlanetPlan(WorldPlan):
    """The planet world's plan: one static scene, ``centre_truth`` rows per frame."""

    body: object = None  # PlanetBody
    info: dict = field(default_factory=dict)

    def frame_meta(self, spec, scene) -> dict:
        meta = super().frame_meta(spec, scene)
        meta["planet"] = dict(self.info)
        return meta

    def frame_rows(self, spec, rendered) -> dict[str, list[dict]]:
        from renderlab.worlds.planet.truth import centre_truth_row

        return {"centre_truth": [centre_truth_row(spec, self.body)]}


def planned_frames(scenario, base_dir: Path, body) -> list:
    """The frame specs: the ``planet_approach`` path, or any camera path / file trajectory via ``frame_specs``."""
    from renderlab.geometry.camera import CameraModel
    from renderlab.render.scene import FrameSpec, SunSpec
    from renderlab.worlds.base import frame_specs
    from renderlab.worlds.planet.path import approach_poses

    if scenario.trajectory.kind != "planet_approach":
        return frame_specs(scenario, base_dir)
    camera = CameraModel.from_dict(scenario.camera.model_dump())
    s = np.asarray(scenario.sun.direction, float)
    sun = SunSpec(direction_render=s / np.linalg.norm(s), irradiance_w_m2=scenario.sun.irradiance_w_m2)
    poses = approach_poses(scenario.trajectory, sun.direction_render, body.centre_m)
    return [FrameSpec(index=k, pose=p, camera=camera, sun=sun) for k, p in enumerate(poses)]


def make_plan(scenario, base_dir: Path) -> PlanetPlan:
    """World plan of a planet scenario (module docstring)."""
    from renderlab.render.scene import SceneDescription
    from renderlab.worlds.planet.body import build_body
    from renderlab.worlds.planet.path import check_frames, render_origin

    world = scenario.world
    body = build_body(world)
    frames = planned_frames(scenario, Path(base_dir), body)
    check_frames(frames, body, scenario.render.far_clip_m)
    origin, bound = render_origin(frames, body, world.origin_tolerance_px)
    info = {"preset": world.preset, "limb_model": body.limb_model,
            "semi_axes_m": [float(v) for v in body.semi_axes_m],
            "centre_m": [float(v) for v in body.centre_m],
            "quat_render_from_principal_xyzw": _quat(body.R_render_from_principal),
            "render_origin_m": [float(v) for v in origin], "float32_bound_px": bound}
    scene = SceneDescription(bodies=[body.spec], render_frame=dict(RENDER_FRAME), origin_m=origin)
    return PlanetPlan(frames=frames, render_frame=dict(RENDER_FRAME), static_scene=scene, body=body, info=info)


def _quat(R) -> list[float]:
    from renderlab.geometry.rotations import quat_xyzw
    from scipy.spatial.transform import Rotation

    return [float(v) for v in quat_xyzw(Rotation.from_matrix(R))]
