"""Tiled surfaces: a body a renderer receives as tiles chosen per frame (levels of detail).

A :class:`~renderlab.render.scene.SceneDescription` lists them in ``tiled`` beside its static ``bodies``. A
backend that declares ``supports_tiles = True`` asks every frame for the tiles in view
(:meth:`TiledSurface.select`) and builds (once per process and tile) their meshes from
:meth:`TiledSurface.tile_body`; any other backend gets :meth:`TiledSurface.full_body` as a static body instead
(:meth:`SceneDescription.untiled`). Example: :class:`renderlab.worlds.ev5.tiles.TiledSite`.
"""

from __future__ import annotations

from typing import Hashable, Protocol, runtime_checkable


@runtime_checkable
class TiledSurface(Protocol):
    name: str
    body_id: int
    law: object  # the surface's PhotometricLaw (all tiles share it)

    def select(self, camera, pose) -> list[Hashable]:
        """Keys of the tiles to render for a camera model at a pose (render frame); each key has a ``name``."""

    def tile_body(self, key):
        """The trimesh :class:`~renderlab.render.scene.BodySpec` of one tile (render frame = body frame)."""

    def full_body(self):
        """The whole surface at full resolution as one trimesh body."""

    def state(self) -> dict:
        """JSON-able description for the manifest (as ``BodySpec.state``)."""

    #: set before each frame by a backend that traces the whole surface at full resolution instead of asking for tiles
    #: (Mitsuba's DEM march, :mod:`renderlab.render.mitsuba_dem`), and cleared by one that asks for tiles: what that
    #: frame rendered, as the world records it, is then the full surface, with no level-of-detail error
    traced_whole: bool
