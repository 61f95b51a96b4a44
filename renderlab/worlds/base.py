"""What a world gives the render pipeline: a :class:`WorldPlan`.

Every world kind (``analytic``, ``ev5``, ``earth``, ``microsat``) registers a
``make_plan(scenario, base_dir) -> WorldPlan`` (:data:`renderlab.plugins.worlds`). The pipeline (``renderlab.pipeline``) is
world-agnostic: it asks the plan for the frames (camera, pose, sun), for the scene each frame needs
(most worlds have one scene for all frames, loaded once and updated in place; Earth renders a new
local tangent tile per footprint), for extra per-frame metadata and truth-table rows, and for the
static files a truth set of that world carries (EV5: landmark catalog and maplets).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Hashable

import numpy as np

from renderlab.dynamics.camera_paths import camera_path
from renderlab.errors import UserError
from renderlab.geometry.camera import CameraModel
from renderlab.render.scene import FrameSpec, RenderedFrame, SceneDescription, SunSpec


@dataclass
class WorldPlan:
    """The frames of a scenario and the scenes they are rendered from.

    Subclass (or fill the fields of) this for each world. Defaults give one static scene.

    Attributes
    ----------
    frames : list of FrameSpec
        Camera model, pose (render frame) and sun of every frame, in order.
    render_frame : dict
        The manifest's top-level ``render_frame`` (``{"name": "EV5_FIXED"}``, ...).
    static_scene : SceneDescription or None
        The scene of every frame when the world has only one.
    """

    frames: list[FrameSpec]
    render_frame: dict = field(default_factory=lambda: {"name": "SCENE"})
    static_scene: SceneDescription | None = None

    def scene_key(self, spec: FrameSpec) -> Hashable:
        """Frames with equal keys share one loaded scene (the backend is rebuilt when it changes)."""
        return 0

    def scene(self, key: Hashable) -> SceneDescription:
        """The scene for ``key`` (from :meth:`scene_key`)."""
        if self.static_scene is None:
            raise NotImplementedError("a world without a static scene must override scene()")
        return self.static_scene

    def frame_meta(self, spec: FrameSpec, scene: SceneDescription) -> dict:
        """Extra manifest entries for this frame (``bodies`` true states, per-frame ``render_frame``, the frame's
        ``epoch_utc`` when its trajectory has epochs, ...)."""
        meta = {"bodies": {b.name: b.state() for b in scene.bodies}}
        epoch = getattr(spec.pose, "epoch_utc", None)
        if epoch:
            meta["epoch_utc"] = epoch
        return meta

    def write_static(self, writer) -> None:
        """Write files every truth set of this world carries (catalogs, maplets, databases)."""

    def spec_at(self, time_s: float, pose) -> FrameSpec:
        """The world at time ``time_s`` (s, the trajectory's clock) seen from camera ``pose`` (render frame), for the
        frame API between planned frames (``Renderer.frame(time_s=...)``); its index follows the planned ones.

        This default serves worlds whose scene, camera model and sun are the same in every planned frame (the
        analytic world); others override it (EV5: the sun turned with the spin) or refuse, as here, with one line."""

        f0 = self.frames[0]
        same = all(np.array_equal(f.sun.direction_render, f0.sun.direction_render)
                   and f.sun.irradiance_w_m2 == f0.sun.irradiance_w_m2 and self.scene_key(f) == self.scene_key(f0)
                   for f in self.frames)
        if not same or getattr(self, "scene_follows_pose", False):
            raise UserError(f"this world ({self.render_frame.get('name', '?')}) has no state between its planned "
                            "frames; render a planned frame (index=) instead of a time")
        return FrameSpec(index=len(self.frames) + self._next_extra(), pose=pose, camera=f0.camera, sun=f0.sun)

    def _next_extra(self) -> int:
        """A new index for a frame between the planned ones (counted per plan)."""
        n = getattr(self, "_extra_frames", 0)
        self._extra_frames = n + 1
        return n

    def frame_rows(self, spec: FrameSpec, rendered: RenderedFrame) -> dict[str, list[dict]]:
        """Truth-table rows for this frame: ``{table_name: [row, ...]}``; the pipeline writes
        ``<table_name>.parquet`` with all frames' rows at the end."""
        return {}


def frame_specs(scenario, base_dir: Path | None = None) -> list[FrameSpec]:
    """Camera, pose and sun of every frame of a scenario whose trajectory is a camera path (line/orbit, or a
    file trajectory: table/ccsds/spice, whose relative paths resolve against ``base_dir``, the scenario folder)."""
    camera = CameraModel.from_dict(scenario.camera.model_dump())
    s = np.asarray(scenario.sun.direction, float)
    sun = SunSpec(direction_render=s / np.linalg.norm(s), irradiance_w_m2=scenario.sun.irradiance_w_m2)
    poses = camera_path(scenario.trajectory, base_dir)
    return [FrameSpec(index=k, pose=p, camera=camera, sun=sun) for k, p in enumerate(poses)]


def make_plan(scenario, base_dir: Path) -> WorldPlan:
    """The :class:`WorldPlan` of ``scenario``: the world kind's registered ``make_plan``
    (:data:`renderlab.plugins.worlds`)."""
    from renderlab import plugins

    world = plugins.worlds.get(scenario.world.kind, where="world.kind: ")
    return world.plan(scenario, Path(base_dir))
