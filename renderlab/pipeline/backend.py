"""A scenario's renderer: the registered backend made for a scene with the scenario's render settings (shared by
:mod:`renderlab.pipeline` and the warm frame API, :mod:`renderlab.pipeline.frame_api`)."""

from __future__ import annotations

from renderlab import plugins
from renderlab.errors import UserError
from renderlab.render.scene import RenderSettings
from renderlab.scenario import Scenario


def make_backend(scenario: Scenario, scene, renderer: str):
    """The registered renderer ``renderer`` (:data:`renderlab.plugins.renderers`) made for ``scene`` with the
    scenario's render settings; a renderer without per-frame tiles gets the untiled scene. An unreadable mesh is
    one :class:`~renderlab.errors.UserError` line naming the body."""
    settings = RenderSettings(
        variant=scenario.render.variant,
        spp=scenario.render.spp,
        max_depth=scenario.render.max_depth,
        pixel_filter=scenario.render.pixel_filter,
        shadows=scenario.render.shadows,
        near_clip_m=scenario.render.near_clip_m,
        far_clip_m=scenario.render.far_clip_m,
    )
    backend_cls = plugins.renderers.get(renderer, where="render.renderer: ")
    if getattr(scene, "tiled", None) and not getattr(backend_cls, "supports_tiles", False):
        scene = scene.untiled()  # a renderer without per-frame tiles gets the full-resolution surface
    try:
        return backend_cls(scene, settings)
    except RuntimeError as exc:  # Mitsuba reports an unreadable mesh as 'At dictionary node "bodyK": ...'
        for body in scene.bodies:
            if body.mesh_path is not None and f'"body{body.body_id}"' in str(exc):
                detail = str(exc).rsplit("] ", 1)[-1]
                raise UserError(f"world.bodies.{body.body_id}.file: cannot load mesh "
                                f"{body.mesh_path.name}: {detail}") from None
        raise
