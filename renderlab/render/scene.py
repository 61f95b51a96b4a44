"""The renderer-neutral scene description.

One :class:`SceneDescription` (bodies with a photometric law and albedo) plus one
:class:`FrameSpec` per frame (time, camera model and pose, sun) is all a backend needs. Backends
(Mitsuba here, Cycles later) turn it into their own scene and return a :class:`RenderedFrame`
whose arrays follow the lab's conventions (docs/architecture.md: pixel centres at integers, P in the render
frame, range in metres from the camera centre, id −1 where nothing was hit).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from renderlab.dynamics.camera_paths import CameraPose
from renderlab.geometry.camera import CameraModel
from renderlab.photometry import PhotometricLaw


@dataclass(frozen=True)
class BodySpec:
    """A rigid body: ``p_render = R_render_from_body @ p_body + center_m``.

    ``shape`` is ``sphere`` (``radius_m``), ``box`` (``size_m`` = 3 edge lengths), ``plane``
    (``size_m`` = 2 edge lengths, normal +z of the body frame), ``mesh`` (``mesh_path``: an OBJ, PLY,
    STL or GLB file in metres in the body frame, read by :mod:`renderlab.render.mesh_io`, which both
    backends turn into the ``trimesh`` form; ``face_normals`` False shades it smooth) or ``trimesh``
    (in-memory ``vertices`` (V, 3) float64 in metres in the body frame and ``faces`` (F, 3) int,
    counter-clockwise seen from outside; flat facets unless ``vertex_normals`` (V, 3) unit normals in the
    body frame are given). ``albedo_map`` (H, W) multiplies ``albedo`` through the surface's uv coordinates;
    ``vertex_albedo`` (V,) multiplies it per vertex of a trimesh (interpolated over each facet);
    ``vertex_uv`` (V, 2) gives a trimesh texture coordinates for ``albedo_map`` (u → map column left to
    right, v → map row top to bottom: the centre of map pixel (row, col) is at u = (col + ½)/W,
    v = (row + ½)/H; a test pins it).
    """

    name: str
    body_id: int
    shape: str
    center_m: np.ndarray
    R_render_from_body: np.ndarray
    law: PhotometricLaw
    albedo: float
    radius_m: float | None = None
    size_m: tuple[float, ...] | None = None
    mesh_path: Path | None = None
    albedo_map: np.ndarray | None = None
    face_normals: bool = True
    vertices: np.ndarray | None = None
    faces: np.ndarray | None = None
    vertex_albedo: np.ndarray | None = None
    vertex_uv: np.ndarray | None = None
    vertex_normals: np.ndarray | None = None

    def state(self) -> dict:
        """JSON-able true state for the manifest."""
        from scipy.spatial.transform import Rotation

        out = {
            "id": self.body_id,
            "shape": self.shape,
            "center_m": [float(v) for v in self.center_m],
            "quat_render_from_body_xyzw": [float(v) for v in Rotation.from_matrix(self.R_render_from_body).as_quat()],
            "law": self.law.to_dict(),
            "albedo": float(self.albedo),
        }
        if self.radius_m is not None:
            out["radius_m"] = float(self.radius_m)
        if self.size_m is not None:
            out["size_m"] = [float(v) for v in self.size_m]
        if self.faces is not None:
            out["n_faces"] = int(len(self.faces))
        return out


@dataclass(frozen=True)
class SunSpec:
    """Directional sun: ``direction_render`` is the unit vector from the scene toward the sun."""

    direction_render: np.ndarray
    irradiance_w_m2: float

    def to_dict(self) -> dict:
        return {"direction_render": [float(v) for v in self.direction_render], "irradiance_w_m2": float(self.irradiance_w_m2)}


@dataclass(frozen=True)
class FrameSpec:
    index: int
    pose: CameraPose
    camera: CameraModel
    sun: SunSpec


@dataclass
class SceneDescription:
    """Bodies of one scene, in the render frame ``render_frame``.

    ``origin_m`` (optional, render frame, m) is the point the backends build their float32 scenes
    around: geometry and camera are shifted by −origin_m in float64 before the renderer sees them, and
    positions come back in the render frame. Put it where the finest geometry is (EV5: the landing
    site). Far from the origin float32 loses detail, and Mitsuba offsets every shadow-ray origin by
    (1 + max|p|)·8.9e-5 m: about 2 cm at the 200 m of EV5-fixed coordinates, enough for shadow rays to
    pass over 5 cm relief at grazing sun (measured: results/crosscheck/README.md).
    ``tiled`` surfaces go to a backend with ``supports_tiles`` as they are, to any other as
    :meth:`untiled` (``renderlab.pipeline.make_backend``).
    """

    bodies: list[BodySpec]
    render_frame: dict = field(default_factory=lambda: {"name": "SCENE"})
    origin_m: np.ndarray | None = None
    #: bodies given as tiles chosen per frame (:class:`renderlab.contracts.tiled.TiledSurface`)
    tiled: list = field(default_factory=list)

    def untiled(self) -> "SceneDescription":
        """The same scene with every tiled surface as one full-resolution static body."""
        if not self.tiled:
            return self
        return SceneDescription([*self.bodies, *(t.full_body() for t in self.tiled)], self.render_frame,
                                self.origin_m)


@dataclass(frozen=True)
class RenderSettings:
    variant: str = "llvm_ad_mono"
    spp: int = 16
    max_depth: int = 2
    pixel_filter: str = "box"  # "box" (spp samples uniform over the pixel) or "center" (one sample)
    shadows: bool = True  # False: no cast shadows (shadow rays off; direct sunlight, max_depth 2, only)
    near_clip_m: float = 1e-3
    far_clip_m: float = 1e7


@dataclass
class RenderedFrame:
    """Float arrays of one frame: radiance (H, W) or (H, W, 3) in W m⁻² sr⁻¹, position and normal
    (H, W, 3) in the render frame (NaN where nothing was hit), range (H, W) in metres (float64,
    from position), id (H, W) int32 (−1 = no hit)."""

    radiance: np.ndarray
    position: np.ndarray
    normal: np.ndarray
    range_m: np.ndarray
    body_id: np.ndarray

    def exr_channels(self) -> dict[str, np.ndarray]:
        ch: dict[str, np.ndarray] = {}
        if self.radiance.ndim == 2:
            ch["Y"] = self.radiance
        else:
            ch.update(R=self.radiance[..., 0], G=self.radiance[..., 1], B=self.radiance[..., 2])
        for k, axis in enumerate("XYZ"):
            ch[f"P.{axis}"] = self.position[..., k]
            ch[f"N.{axis}"] = self.normal[..., k]
        ch["range"] = self.range_m
        ch["id"] = self.body_id
        return {k: np.ascontiguousarray(v, dtype=np.float32) for k, v in ch.items()}
