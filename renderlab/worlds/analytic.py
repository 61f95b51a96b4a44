"""Analytic worlds: spheres, boxes and planes (and user meshes) whose truth is known exactly.

They prove the renderers: a Lambert sphere in sunlight has radiance A·E·cos(i)/π, a box on a
plane casts a shadow whose edge is the projection of the box's edge along the sun direction.

User meshes (``shape = "mesh"``: OBJ, PLY, STL or GLB, ``units``, ``normals``) are read by
:mod:`renderlab.render.mesh_io` into in-memory triangle meshes, which every backend renders.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from renderlab.errors import UserError
from renderlab.inputs import shown
from renderlab.photometry import make_law
from renderlab.render.scene import BodySpec, SceneDescription


def load_albedo_map(path: Path) -> np.ndarray:
    """Read an 8/16-bit grey image (PNG, TIFF, ...) or a float EXR/NPY-free image as values in [0, 1]."""
    import cv2

    from renderlab.contracts.image_headers import image_header

    image_header(path, "albedo map")  # a regular file whose header says a sane size, before anything is decoded
    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED | cv2.IMREAD_ANYDEPTH)
    if img is None:
        raise UserError(f"albedo map {shown(path.name)} could not be read as an image")
    if img.ndim == 3:
        img = img.mean(axis=2)
    if np.issubdtype(img.dtype, np.integer):
        img = img.astype(np.float64) / np.iinfo(img.dtype).max
    img = np.asarray(img, np.float64)
    if not np.all(np.isfinite(img)) or img.min() < 0:
        raise UserError(f"albedo map {shown(path.name)} has negative or non-finite values")
    return img


def _mesh_arrays(b, k: int, base_dir: Path) -> dict:
    """BodySpec fields of a ``shape = "mesh"`` body: the file read by :func:`renderlab.render.mesh_io.load_mesh`."""
    from renderlab.render.mesh_io import load_mesh

    where = f"world.bodies.{k}.file"
    mesh = load_mesh((base_dir / b.file).resolve(), units=b.units or "m", normals=b.normals or "flat", where=where)
    if b.albedo_map and mesh.vertex_uv is None:
        raise UserError(f"world.bodies.{k}.albedo_map: {mesh.source} has no texture coordinates to map it with")
    return {"shape": "trimesh", "vertices": mesh.vertices, "faces": mesh.faces,
            "vertex_normals": mesh.vertex_normals, "vertex_uv": mesh.vertex_uv if b.albedo_map else None,
            "face_normals": mesh.vertex_normals is None}


def build_scene(world, base_dir: Path) -> SceneDescription:
    """Scene description of a :class:`renderlab.scenario.AnalyticWorld` (ids follow the body order).

    Parameters
    ----------
    world : AnalyticWorld
        The validated world section.
    base_dir : pathlib.Path
        Folder that mesh and albedo-map paths are relative to.

    Returns
    -------
    SceneDescription
        One body per entry; ``shape = "mesh"`` bodies arrive as in-memory ``trimesh`` bodies (vertices in
        metres after ``units``, ``normals`` flat or smooth), the same array path every backend renders.
    """
    bodies = []
    for k, b in enumerate(world.bodies):
        mesh = _mesh_arrays(b, k, base_dir) if b.shape == "mesh" else {"shape": b.shape}
        amap = load_albedo_map((base_dir / b.albedo_map).resolve()) if b.albedo_map else None
        try:
            law = make_law(b.law, **b.law_params)
        except UserError as err:
            raise UserError(f"world.bodies.{k}: {err}") from None
        bodies.append(
            BodySpec(
                name=b.name,
                body_id=k,
                center_m=np.asarray(b.center_m, float),
                R_render_from_body=Rotation.from_euler("xyz", b.rotation_deg, degrees=True).as_matrix(),
                law=law,
                albedo=b.albedo,
                radius_m=b.radius_m,
                size_m=tuple(b.size_m) if b.size_m else None,
                albedo_map=amap,
                **mesh,
            )
        )
    return SceneDescription(bodies=bodies, render_frame={"name": "SCENE"})


def spice_suns(scenario, base_dir, frames: list) -> list:
    """``frames`` with the sun of each taken from the trajectory's SPICE kernels (``sun.source = "spice"``): the
    direction from the trajectory's centre toward the Sun, the irradiance ``sun.irradiance_w_m2`` (at 1 AU) over
    the squared distance in AU (:func:`renderlab.trajectory_io.sources.spice_sun`)."""
    from dataclasses import replace

    from renderlab.render.scene import SunSpec
    from renderlab.trajectory_io.sources import spice_sun

    au = 149597870700.0
    out = []
    for spec, v in zip(frames, spice_sun(scenario.trajectory, base_dir)):
        d = float(np.linalg.norm(v))
        out.append(replace(spec, sun=SunSpec(direction_render=v / d,
                                             irradiance_w_m2=scenario.sun.irradiance_w_m2 * (au / d) ** 2)))
    return out


def make_plan(scenario, base_dir: Path):
    """World plan of an analytic scenario: one static scene, frames from ``trajectory`` (line/orbit/files); the sun
    of ``[sun]``, or of the SPICE kernels per frame with ``sun.source = "spice"`` (:func:`spice_suns`). With a file
    trajectory the scene frame is the files' frame: the render frame records the names the files give it, its origin
    and the camera body (``source_frame``, ``source_center``, ``source_object``; ``renderlab export`` keeps them)."""
    from renderlab.worlds.base import WorldPlan, frame_specs

    frames = frame_specs(scenario, base_dir)
    if getattr(scenario.sun, "source", "direction") == "spice":
        frames = spice_suns(scenario, base_dir, frames)
    render_frame = {"name": "SCENE"}
    if scenario.trajectory.kind in ("table", "ccsds", "spice"):  # the scene frame is the files' frame: keep names
        from renderlab.trajectory_io.sources import source_names

        render_frame.update({f"source_{k}": v for k, v in source_names(scenario.trajectory, base_dir).items()})
    return WorldPlan(frames=frames, render_frame=render_frame, static_scene=build_scene(scenario.world, base_dir))
