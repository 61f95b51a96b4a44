"""Blender Cycles backend: the same :class:`SceneDescription` → radiance and truth AOVs, a second,
independent renderer for the cross-check (``renderlab crosscheck``).

Cycles runs in one worker subprocess per backend (:mod:`renderlab.render.cycles_job`; bpy import
costs seconds, the scene is built once), fed through files in a temporary folder (JSON, npz without
pickle, multilayer float EXR). Mapping to the lab's conventions:

* Camera (pinhole only: skew and lens distortion raise a UserError — Cycles' camera would need an OSL
  custom camera for those, and the cross-check is about the renderer, not the camera model). With
  horizontal sensor fit, sensor width w_s and W×H pixels (Blender's ``BKE_camera_params_compute_viewplane``):
  ``lens = f_x w_s / W``; pixel aspect y/x = f_x/f_y; and because Blender puts pixel *corners* at
  integers while the lab puts the centre of the top-left pixel at (0, 0), the principal point in
  Blender's raster is (c_x + ½, c_y + ½):
  ``shift_x = (W/2 − c_x − ½)/W``, ``shift_y = (c_y + ½ − H/2)·(f_x/f_y)/W`` (shift in units of the width;
  Blender's y is up). Blender's camera looks along its −z with +y up, so
  ``R_render_from_blender_cam = R_render_from_cam · diag(1, −1, −1)``. A test re-projects the
  position AOV through :class:`CameraModel` (≤ 0.05 px).
* Radiance: ``spp`` samples with a 1-px box filter (each sample uniform over the pixel, as in the
  Mitsuba backend), direct sunlight (max_depth = 2 only), photometric laws as OSL shaders
  (``osl/rl_photometry.osl``, the laws of :mod:`renderlab.photometry`). ``pixel_filter = "center"``
  uses the centre render's radiance instead. ``shadows = false``: no body casts a shadow (every object's
  shadow-ray visibility off, ``Object.visible_shadow``).
* Truth AOVs: a second render with 1 sample and a 0.01-px box filter (Cycles' minimum: the sample lies
  within ±0.005 px of the pixel centre): Position (render frame), Normal (shading normal), IndexOB
  (object ``pass_index`` = body id + 1, 0 = miss → id −1). Cycles' Z pass is planar depth; like the
  Mitsuba backend, the lab's range is ‖P − camera‖ in float64.
* Shapes: Mitsuba's sphere is analytic; here it is a smooth-shaded latitude-longitude mesh
  (``SPHERE_SEGMENTS`` × ``SPHERE_SEGMENTS/2``, exact radial vertex normals): the facets lie inside the
  sphere by at most R(1 − cos(π/SPHERE_SEGMENTS)) ≈ 1.9e-5 R. Box and plane are exact; trimesh bodies
  keep their flat facets (or their ``vertex_normals``, smooth), per-vertex albedo (a float point
  attribute) and uv + albedo map. Mesh files (OBJ/PLY/STL/GLB) are read by :mod:`renderlab.render.mesh_io`
  into the same arrays. Albedo maps on sphere/box/plane are not supported yet (UserError).
* ``--save-blend`` (:func:`saving_blend`): the worker saves the first frame's scene as a .blend after
  rendering it (OSL source embedded, images packed, relative paths; coordinates are the float32 local
  ones around ``origin_m``).
* Blender objects are float32: coordinates of magnitude X keep ≈ X·6e-8 m. Like the Mitsuba backend,
  geometry and camera are built around ``SceneDescription.origin_m`` (shifted in float64; P shifted back).
"""

from __future__ import annotations

import contextlib
import contextvars
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from renderlab.errors import UserError
from renderlab.extras import require
from renderlab.render.mesh_io import mesh_body
from renderlab.render.scene import BodySpec, FrameSpec, RenderedFrame, RenderSettings, SceneDescription

OSL_PATH = Path(__file__).parent / "osl" / "rl_photometry.osl"
SPHERE_SEGMENTS = 512
SENSOR_WIDTH_MM = 36.0
CENTRE_FILTER_PX = 0.01
BLENDER_CAM_FROM_CAM = np.diag([1.0, -1.0, -1.0])  # lab camera (+z boresight, +y down) → Blender's


def blender_camera(camera) -> dict:
    """Blender camera and film settings reproducing a pinhole :class:`CameraModel` (see module doc)."""
    if camera.model != "pinhole" or any(float(v) != 0.0 for v in camera.distortion.values()):
        raise UserError("cycles backend supports pinhole cameras only (camera.model = 'pinhole', no distortion)")
    if float(camera.skew) != 0.0 or float(getattr(camera, "skew_yx", 0.0)) != 0.0:
        raise UserError("cycles backend supports pinhole cameras only (camera.skew must be 0)")
    W, H = int(camera.width), int(camera.height)
    fx, fy = float(camera.fx), float(camera.fy)
    ratio = fx / fy  # Blender's pixel aspect y/x
    return {
        "width": W,
        "height": H,
        "sensor_width_mm": SENSOR_WIDTH_MM,
        "lens_mm": fx * SENSOR_WIDTH_MM / W,
        "pixel_aspect_x": 1.0 / ratio if ratio < 1.0 else 1.0,  # Blender wants both >= 1
        "pixel_aspect_y": ratio if ratio >= 1.0 else 1.0,
        "shift_x": (W / 2.0 - float(camera.cx) - 0.5) / W,
        "shift_y": (float(camera.cy) + 0.5 - H / 2.0) * ratio / W,
    }


def _sun_lamp_matrix(direction) -> list[list[float]]:
    """4×4 world matrix of a Blender sun lamp whose light travels along −direction (lamp −z)."""
    z = np.asarray(direction, float)
    z = z / np.linalg.norm(z)
    a = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(a, z)
    x /= np.linalg.norm(x)
    M = np.eye(4)
    M[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    return M.tolist()


def _uv_sphere(segments: int):
    """Unit latitude-longitude sphere: vertices (V, 3) and CCW triangles (F, 3)."""
    n_lon, n_lat = segments, segments // 2
    theta = np.linspace(0.0, np.pi, n_lat + 1)[1:-1]
    phi = np.arange(n_lon) * 2 * np.pi / n_lon
    t, p = np.meshgrid(theta, phi, indexing="ij")
    ring = np.column_stack([(np.sin(t) * np.cos(p)).ravel(), (np.sin(t) * np.sin(p)).ravel(), np.cos(t).ravel()])
    V = np.vstack([[0.0, 0.0, 1.0], ring, [0.0, 0.0, -1.0]])
    south = len(V) - 1
    idx = lambda i, j: 1 + i * n_lon + (j % n_lon)  # noqa: E731
    j = np.arange(n_lon)
    faces = [np.column_stack([np.zeros(n_lon, int), idx(0, j), idx(0, j + 1)])]
    for i in range(n_lat - 2):
        a, b, c, d = idx(i, j), idx(i, j + 1), idx(i + 1, j), idx(i + 1, j + 1)
        faces += [np.column_stack([a, c, d]), np.column_stack([a, d, b])]
    faces.append(np.column_stack([idx(n_lat - 2, j), np.full(n_lon, south), idx(n_lat - 2, j + 1)]))
    return V, np.vstack(faces)


def _box():
    V = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    F = [(a, b, c) for a, b, c, d in quads] + [(a, c, d) for a, b, c, d in quads]
    return V, np.array(F)


def body_mesh(body: BodySpec) -> dict:
    """Render-frame triangle mesh arrays of a body: ``v``, ``f`` and optional ``n``, ``va``, ``uv``, ``map``.

    Parameters
    ----------
    body : BodySpec
        Any body; a mesh file (``shape = "mesh"``) is read by :mod:`renderlab.render.mesh_io`.

    Returns
    -------
    dict
        ``v`` (V, 3) render-frame vertices, ``f`` (F, 3) triangles, ``n`` (V, 3) render-frame vertex normals
        (smooth shading), ``va`` per-vertex albedo, ``uv`` texture coordinates, ``map`` albedo map.
    """
    body = mesh_body(body)
    R, c = np.asarray(body.R_render_from_body, float), np.asarray(body.center_m, float)
    out: dict = {}
    if body.albedo_map is not None and not (body.shape == "trimesh" and body.vertex_uv is not None):
        raise UserError(f"cycles backend: body '{body.name}': albedo maps are supported on trimesh bodies "
                        "with vertex_uv only")
    if body.shape == "sphere":
        V, F = _uv_sphere(SPHERE_SEGMENTS)
        out["n"] = V @ R.T
        V = V * float(body.radius_m)
    elif body.shape == "box":
        V, F = _box()
        V = V * np.asarray(body.size_m, float)
    elif body.shape == "plane":
        sx, sy = body.size_m
        V = np.array([[-sx / 2, -sy / 2, 0.0], [sx / 2, -sy / 2, 0.0], [sx / 2, sy / 2, 0.0], [-sx / 2, sy / 2, 0.0]])
        F = np.array([[0, 1, 2], [0, 2, 3]])
    elif body.shape == "trimesh":
        V, F = np.asarray(body.vertices, np.float64), np.asarray(body.faces, np.int64)
        if body.vertex_albedo is not None:
            out["va"] = np.asarray(body.vertex_albedo, np.float32)
        if body.vertex_uv is not None:
            out["uv"] = np.asarray(body.vertex_uv, np.float32)
        if body.albedo_map is not None:
            out["map"] = np.asarray(body.albedo_map, np.float32)
        if body.vertex_normals is not None:
            out["n"] = np.asarray(body.vertex_normals, np.float64) @ R.T
    else:
        raise UserError(f"cycles backend: body '{body.name}': shape '{body.shape}' is not supported "
                        "(sphere, box, plane, mesh and trimesh are)")
    out["v"] = V @ R.T + c
    out["f"] = np.asarray(F, np.int64)
    return out


#: while set ({"path": str, "saved": bool}), the next frame a CyclesBackend renders is also saved as a .blend
_SAVE_BLEND: contextvars.ContextVar[dict | None] = contextvars.ContextVar("renderlab_save_blend", default=None)


def check_blend_target(path: str | Path, renderer: str, *, overwrite: bool = False) -> Path:
    """The absolute path for ``--save-blend``, or a one-line UserError.

    Parameters
    ----------
    path : str or pathlib.Path
        Requested ``.blend`` file.
    renderer : str
        The renderer the command will use (must be ``cycles``).
    overwrite : bool
        Whether an existing file may be replaced.

    Returns
    -------
    pathlib.Path
        The resolved path (its folder exists).
    """
    if renderer != "cycles":
        raise UserError(f"--save-blend needs the Cycles renderer (--renderer cycles); this render uses '{renderer}'")
    target = Path(path).expanduser().resolve()
    if target.suffix.lower() != ".blend":
        raise UserError(f"--save-blend: {Path(path).name} must end in .blend")
    if not target.parent.is_dir():
        raise UserError(f"--save-blend: folder {target.parent} does not exist")
    if target.is_dir() or (target.exists() and not overwrite):
        raise UserError(f"--save-blend: {target} already exists (pass --overwrite to replace it)")
    return target


@contextlib.contextmanager
def saving_blend(path: Path | None):
    """Within this block, the first frame any :class:`CyclesBackend` renders is also saved to ``path``.

    Parameters
    ----------
    path : pathlib.Path or None
        Absolute ``.blend`` path; None makes the block a no-op.

    Yields
    ------
    dict or None
        ``{"path": str, "saved": bool}``: ``saved`` turns True once the worker wrote the file.
    """
    if path is None:
        yield None
        return
    state = {"path": str(path), "saved": False}
    token = _SAVE_BLEND.set(state)
    try:
        yield state
    finally:
        _SAVE_BLEND.reset(token)


def _read_multilayer(path: Path) -> dict[str, np.ndarray]:
    """Channels of a Blender multilayer EXR (one part per pass) keyed by the last two name parts ('Combined.R')."""
    import OpenEXR

    out = {}
    with OpenEXR.File(str(path), separate_channels=True) as f:
        for part in f.parts:
            for name, ch in part.channels.items():
                out[".".join(name.split(".")[-2:])] = np.asarray(ch.pixels, np.float32)
    return out


class CyclesBackend:
    """Render frames of one scene with Blender Cycles in a worker subprocess (scene built once)."""

    name = "cycles"

    def __init__(self, scene: SceneDescription, settings: RenderSettings):
        if settings.max_depth != 2:
            raise UserError("cycles backend renders direct sunlight only: render.max_depth must be 2, "
                            f"got {settings.max_depth}")

        require("bpy", "cycles", load=False)  # the worker imports it (seconds)
        self.settings = settings
        self.variant = "cycles-cpu-osl"
        self.rgb = settings.variant.endswith("rgb")
        self._tmp = tempfile.TemporaryDirectory(prefix="renderlab-cycles-")
        self.workdir = Path(self._tmp.name)
        self.origin = np.zeros(3) if scene.origin_m is None else np.asarray(scene.origin_m, np.float64).reshape(3)
        bodies, arrays = [], {}
        for k, body in enumerate(scene.bodies):
            key = f"b{k}"
            for name, arr in body_mesh(body).items():
                arrays[f"{name}_{key}"] = arr - self.origin if name == "v" else arr
            bodies.append({"key": key, "name": body.name, "body_id": int(body.body_id),
                           "law": body.law.to_dict(), "albedo": float(body.albedo)})
        np.savez(self.workdir / "scene.npz", **arrays)
        # Blender compiles an external .osl and copies the .oso next to it: compile a copy in the
        # worker's folder, so nothing is written into the package (and parallel workers never race)
        osl_copy = self.workdir / OSL_PATH.name
        shutil.copyfile(OSL_PATH, osl_copy)
        (self.workdir / "scene.json").write_text(json.dumps({"bodies": bodies, "osl_path": str(osl_copy),
                                                              "shadows": bool(settings.shadows)}))
        env = {**os.environ, "PYTHONUNBUFFERED": "1"}
        self._proc = subprocess.Popen(
            [sys.executable, "-m", "renderlab.render.cycles_job", str(self.workdir)],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env,
            cwd=str(Path(__file__).resolve().parents[2]),
        )
        self.version = self._expect("ready")
        self._n = 0

    # ------------------------------------------------------------------ worker protocol
    def _expect(self, what: str) -> str:
        line = self._proc.stdout.readline()
        while line and not line.startswith("RLJOB "):
            line = self._proc.stdout.readline()
        if not line:
            tail = self._log_tail()
            self.close()
            raise RuntimeError(f"Cycles worker exited unexpectedly; worker.log ends with:\n{tail}")
        _, kind, rest = (line.rstrip("\n").split(" ", 2) + [""])[:3]
        if kind == "error":
            raise RuntimeError(f"Cycles worker: {rest}; worker.log ends with:\n{self._log_tail()}")
        if kind != what:
            raise RuntimeError(f"Cycles worker: expected '{what}', got {line!r}")
        return rest

    def _log_tail(self) -> str:
        log = self.workdir / "worker.log"
        return "\n".join(log.read_text(errors="replace").splitlines()[-20:]) if log.is_file() else "(no log)"

    def close(self) -> None:
        """Stop the worker and remove its folder (also done when the backend is garbage-collected)."""
        proc = getattr(self, "_proc", None)
        if proc is not None and proc.poll() is None:
            try:
                proc.stdin.close()
                proc.wait(timeout=30)
            except (OSError, subprocess.TimeoutExpired):
                proc.kill()
                proc.wait()
        if proc is not None and proc.stdout is not None:
            proc.stdout.close()
        self._proc = None
        tmp = getattr(self, "_tmp", None)
        if tmp is not None:
            tmp.cleanup()
            self._tmp = None

    def __del__(self):
        try:
            self.close()
        except Exception:  # noqa: BLE001 - interpreter shutdown
            pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # ------------------------------------------------------------------ per frame
    def render(self, frame: FrameSpec, seed: int) -> RenderedFrame:
        """Render one frame. ``seed`` fixes Cycles' sampler (same seed → same pixels)."""
        cam = frame.camera
        W, H = cam.width, cam.height
        T = np.eye(4)
        T[:3, :3] = frame.pose.rotation.as_matrix() @ BLENDER_CAM_FROM_CAM
        cam_local = np.asarray(frame.pose.position_m, float) - self.origin
        T[:3, 3] = cam_local
        self._n += 1
        tag = f"f{self._n:06d}"
        seeds = np.random.SeedSequence(seed).generate_state(2, dtype=np.uint32) % np.uint32(2**31 - 1)
        renders = [{"exr": f"{tag}_centre.exr", "samples": 1, "filter_width_px": CENTRE_FILTER_PX, "seed": int(seeds[0])}]
        if self.settings.pixel_filter == "box":
            renders.append({"exr": f"{tag}_box.exr", "samples": int(self.settings.spp), "filter_width_px": 1.0,
                            "seed": int(seeds[1])})
        job = {
            "camera": blender_camera(cam),
            "T_render_from_blender_cam": T.tolist(),
            "T_render_from_sun_lamp": _sun_lamp_matrix(frame.sun.direction_render),
            "sun_direction_render": (np.asarray(frame.sun.direction_render, float)
                                     / np.linalg.norm(frame.sun.direction_render)).tolist(),
            "irradiance_w_m2": float(frame.sun.irradiance_w_m2),
            "near_clip_m": self.settings.near_clip_m,
            "far_clip_m": self.settings.far_clip_m,
            "renders": renders,
        }
        save = _SAVE_BLEND.get()
        if save is not None and not save["saved"]:
            job["save_blend"] = save["path"]
        (self.workdir / f"{tag}.json").write_text(json.dumps(job))
        if self._proc is None or self._proc.poll() is not None:
            raise RuntimeError("Cycles worker is not running")
        self._proc.stdin.write(f"{tag}.json\n")
        self._proc.stdin.flush()
        self._expect("done")
        if "save_blend" in job:
            save["saved"] = True
        centre = _read_multilayer(self.workdir / renders[0]["exr"])
        beauty = _read_multilayer(self.workdir / renders[-1]["exr"])
        for r in renders:
            (self.workdir / r["exr"]).unlink()
        (self.workdir / f"{tag}.json").unlink()
        for ch in (centre, beauty):
            if ch["Combined.R"].shape != (H, W):
                raise RuntimeError(f"Cycles wrote {ch['Combined.R'].shape}, expected {(H, W)}")
        ids = np.rint(centre["Object Index.X"]).astype(np.int32) - 1
        hit = ids >= 0
        P_local = np.stack([centre[f"Position.{a}"] for a in "XYZ"], axis=-1).astype(np.float64)
        N = np.stack([centre[f"Normal.{a}"] for a in "XYZ"], axis=-1).astype(np.float32)
        P_local[~hit] = np.nan
        N[~hit] = np.nan
        rng_m = np.linalg.norm(P_local - cam_local, axis=-1)
        P = (P_local + self.origin).astype(np.float32)
        rgb = np.stack([beauty[f"Combined.{a}"] for a in "RGB"], axis=-1).astype(np.float32)
        radiance = rgb if self.rgb else rgb.mean(axis=-1, dtype=np.float64).astype(np.float32)
        return RenderedFrame(radiance=radiance, position=P, normal=N, range_m=rng_m, body_id=ids)
