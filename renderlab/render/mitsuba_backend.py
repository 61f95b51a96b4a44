"""Mitsuba 3 backend: a :class:`SceneDescription` → radiance and truth AOVs of one frame.

The lab casts its own primary rays instead of using a Mitsuba sensor, so the image follows the
lab's camera model — any 2×2 pixel map K (fx ≠ fy, skew, off-centre principal point, Retina eq. 4)
and any distortion model — with no resampling. JIT variants (LLVM, CUDA) generate every sample's ray
in the kernel (:mod:`renderlab.render.mitsuba_rays`: a pinhole's inverse pixel map evaluated there,
exact; with distortion a float64 :meth:`CameraModel.unproject` of the pixel-centre grid once per camera,
bilinear inside the pixel, ≤ 3e-3 px) in one wavefront of W·H·spp samples, like ``mi.render``. ``ray_path = "numpy"`` keeps
the former path (every sample's (s, l) through :meth:`CameraModel.unproject` in numpy, one wavefront
per sample) for the benchmarks. The integrator evaluates the radiance along the rays: for direct sunlight
(``max_depth = 2``) the lab's ``rl_direct_sun`` (:mod:`renderlab.render.mitsuba_direct`: primary and shadow
ray, one BSDF evaluation; ``shadows = False`` drops the shadow ray), for longer paths Mitsuba's ``path``;
``integrator = "path"`` keeps ``path`` at ``max_depth = 2`` too (the integrator before ``rl_direct_sun``: a third,
BSDF-sampled ray per sample that cannot reach the delta sun, and a second BSDF evaluation), for the benchmarks.

* Box pixel filter: sample j of pixel (s, l) is at (s, l) + frac(r2_j + u_pix) − ½, with r2_j the
  R2 low-discrepancy sequence and u_pix one uniform shift per pixel (Cranley–Patterson rotation).
  Each sample is uniform over the pixel square, so the mean is the exact box-filtered radiance.
  ``pixel_filter = "center"`` takes one sample at the pixel centre instead (point sampling, for
  validation against closed forms).
* Scalar variants (the fallback when LLVM is unusable) trace the numpy path's rays one at a time
  from Python: identical semantics, much slower (see ``benchmarks/``).
* Truth AOVs come from one ray through each pixel *centre*: position (hit point, render frame),
  shading normal, body id, and range = ‖P − camera‖ computed in float64 from the position.
* Clip planes are planar, like a camera's: a ray starts at depth ``near_clip_m`` and ends at
  depth ``far_clip_m`` along the boresight.
* The scene is loaded once; per frame only the sun (``mi.traverse``) and the rays change.
* Meshes are built from arrays (``mi.Mesh``): in-memory ``trimesh`` bodies, and mesh files read by
  :mod:`renderlab.render.mesh_io` (Mitsuba never parses a mesh file itself); ``vertex_normals`` give
  smooth shading, else facets are flat.
* Geometry and rays are built around ``SceneDescription.origin_m`` (shifted in float64, P shifted
  back): Mitsuba offsets shadow-ray origins by (1 + max|p|)·8.9e-5 m (``RayEpsilon``), which at
  200 m coordinates (≈2 cm) lets sunlight leak under 5 cm relief at grazing incidence.

"""

from __future__ import annotations

import contextlib
import os

import numpy as np

from renderlab.errors import UserError
from renderlab.render.mesh_io import mesh_body
from renderlab.render.mitsuba_bsdf import bsdf_dict, register_bsdfs
from renderlab.render.mitsuba_dem import DemScene
from renderlab.render.mitsuba_direct import integrator_dict, register_direct_sun
from renderlab.render.mitsuba_numpy_path import NumpyRayPath, subpixel_offsets  # noqa: F401  (re-exported)
from renderlab.render.mitsuba_rays import MAX_SAMPLES_PER_PASS, CameraRays, FramePose, aligned_f32, pass_sizes
from renderlab.render.mitsuba_tiles import TileScenes
from renderlab.render.mitsuba_two_scene import TileScene, register_ids, site_design
from renderlab.render.scene import BodySpec, FrameSpec, RenderedFrame, RenderSettings, SceneDescription
from renderlab.render.truth_aovs import truth_aovs
from renderlab.render.variant import init_mitsuba

_aligned_f32 = aligned_f32


def _transform4(R: np.ndarray, t: np.ndarray, scale) -> list[list[float]]:
    M = np.eye(4)
    M[:3, :3] = R @ np.diag(np.broadcast_to(np.asarray(scale, float), (3,)))
    M[:3, 3] = t
    return M.tolist()


#: ``MitsubaBackend.ray_path`` values (``render`` says what each is)
RAY_PATHS = ("drjit", "drjit_grid", "numpy")


def _check_ray_path(ray_path: str) -> None:
    if ray_path not in RAY_PATHS:

        raise UserError(f"Mitsuba ray path (RENDERLAB_MITSUBA_RAYS) must be one of {', '.join(RAY_PATHS)}, "
                        f"got {ray_path!r}")


class MitsubaBackend(NumpyRayPath):
    """Render frames of one scene with Mitsuba 3 (scene loaded once, updated in place)."""

    name = "mitsuba"
    #: tiled surfaces (levels of detail) are chosen per frame (renderlab.render.mitsuba_tiles)
    supports_tiles = True
    #: ``settings.spp`` may change between frames (the frame API's ``spp=``): samples are drawn per render
    per_frame_spp = True
    #: ``"drjit"``: primary rays generated in the kernel (JIT variants, the default); ``"numpy"``: the former
    #: path (float64 numpy rays per sample, one wavefront per sample), kept for the benchmarks; ``"drjit_grid"``:
    #: pinholes through the direction grid, as before commit 7018b77 (:meth:`render`); ``$RENDERLAB_MITSUBA_RAYS``
    ray_path = os.environ.get("RENDERLAB_MITSUBA_RAYS") or "drjit"
    #: ``"auto"``: ``rl_direct_sun`` (renderlab.render.mitsuba_direct) for max_depth 2, else ``path``;
    #: ``"path"``: Mitsuba's ``path`` integrator (the lab's before ``rl_direct_sun``), kept for the benchmarks
    integrator = "auto"
    #: tiled surfaces (renderlab.render.mitsuba_two_scene.site_design): ``"auto"``, the full DEMs marched beside the
    #: static scene where the design applies (LLVM variants with the direct-sun integrator;
    #: renderlab.render.mitsuba_dem), else in the one scene; ``"dem"``, that design on CUDA variants too (not yet
    #: checked on a GPU: benchmarks/gpu_check.sh does); ``"two"``, the frame's LOD tiles in a second scene
    #: (renderlab.render.mitsuba_two_scene); ``"merged"``, the tiles in the one scene (the first design; kept for the
    #: benchmarks and the side-by-side tests); ``$RENDERLAB_MITSUBA_TILE_DESIGN`` sets the default
    tile_design = os.environ.get("RENDERLAB_MITSUBA_TILE_DESIGN") or "auto"
    #: largest wavefront of the Dr.Jit path (samples); more spp are rendered in passes of whole spp
    samples_per_pass = MAX_SAMPLES_PER_PASS

    def __init__(self, scene: SceneDescription, settings: RenderSettings):
        _check_ray_path(self.ray_path)  # before any output: the backend is made before the truth-set writer
        mi = init_mitsuba(settings.variant)
        import drjit as dr


        register_bsdfs(mi)
        register_direct_sun(mi)
        self.mi, self.dr, self.settings = mi, dr, settings
        self.origin = np.zeros(3) if scene.origin_m is None else np.asarray(scene.origin_m, np.float64).reshape(3)
        self.variant = mi.variant()
        self.version = mi.__version__
        self.rgb = self.variant.endswith("rgb")
        self.mono_out = settings.variant.endswith("mono")  # a mono scene rendered by the scalar_rgb fallback
        self.scalar = self.variant.startswith("scalar")
        desc = {
            "type": "scene",
            "integrator": integrator_dict(settings.max_depth, settings.shadows, self.integrator),
            "sun": {"type": "directional", "direction": [0.0, 0.0, -1.0], "irradiance": 1.0},
        }
        keys = {}
        for body in scene.bodies:
            key = f"body{body.body_id}"
            keys[key] = body.body_id
            body = mesh_body(body)  # a mesh file → in-memory arrays (renderlab.render.mesh_io)
            desc[key] = self._trimesh(body, key) if body.shape == "trimesh" else {**self._shape_dict(body), "id": key}
        self._load(desc, keys)
        self._tiles = self._two = None
        self._tiled = []
        if scene.tiled:  # the frame's tiles, chosen before each frame (_set_sun)

            design = site_design(self)
            self._tiled = [(surf, design == "dem") for surf in scene.tiled]
            if design == "dem":  # the full DEMs marched: nothing built per frame, full resolution
                self._tiles = self._two = DemScene(self, scene.tiled, settings.shadows)
            elif design == "two":  # the frame's tiles in a second scene: the static bodies' structure is never rebuilt
                self._tiles = self._two = TileScene(self, scene.tiled, settings.shadows)
            else:  # merged into the one scene (scalar and CUDA variants, Mitsuba's path integrator)
                self._tiles = TileScenes(self, desc, keys, scene.tiled)

    def _load(self, desc: dict, keys: dict) -> None:
        """Load the scene ``desc`` (shape key → body id in ``keys``): parameters, id table, integrator."""
        mi = self.mi
        # optimize=False: no merging of meshes that share a BSDF (each body keeps its own id)
        self.scene = mi.load_dict(desc, optimize=False)
        self.params = mi.traverse(self.scene)
        self._id_lut = np.full(2, -1, dtype=np.int32)
        self._register_shapes(self.scene, keys)
        self._integrator = self.scene.integrator()

    def _register_shapes(self, scene, keys: dict) -> None:
        """Map the registry ids of ``scene``'s shapes (shape key → body id in ``keys``) to body ids."""
        if self.scalar:  # no pointer registry in scalar mode: number the shapes ourselves
            reg = np.arange(1, len(scene.shapes()) + 1, dtype=np.int64)
            self._scalar_reg = reg
        else:
            reg = np.array(self.dr.reinterpret_array(self.mi.UInt32, scene.shapes_dr()), dtype=np.int64)
        self._id_lut = register_ids(self._id_lut, reg, [keys[shape.id()] for shape in scene.shapes()])

    def _hit(self, ray, coherent: bool = True):
        """The first surface interaction along ``ray`` (JIT variants), over both scenes in the two-scene design."""
        if self._two is not None:
            return self._two.first_hit(ray, coherent)
        return self.scene.ray_intersect(ray, ray_flags=self.mi.RayFlags.All, coherent=coherent)

    def _sample(self, sampler, ray):
        """Radiance along ``ray`` (JIT variants): the scene's integrator, or the two-scene direct-sun estimator."""
        if self._two is not None:
            return self._two.direct_sun(sampler, ray)
        spec, _, _ = self._integrator.sample(self.scene, sampler, ray)
        return spec

    # ---------------------------------------------------------------- scene building
    def _albedo_texture(self, body: BodySpec):
        if body.albedo_map is None:
            return float(body.albedo)
        data = np.ascontiguousarray(np.asarray(body.albedo_map, np.float32) * np.float32(body.albedo))
        return {
            "type": "bitmap",
            "bitmap": self.mi.Bitmap(data[..., None] if data.ndim == 2 else data),
            "raw": True,
            "filter_type": "bilinear",
            "wrap_mode": "clamp",
        }

    def _trimesh(self, body: BodySpec, key: str, bsdf=None):
        """A Mitsuba mesh built from in-memory vertices (body frame → render frame in float64); ``bsdf`` (a
        loaded BSDF) is shared when given — the tiles of one surface share one, so a frame with hundreds of
        tiles traces the BSDF once, not once per tile."""
        mi = self.mi

        V = np.asarray(body.vertices, np.float64) @ body.R_render_from_body.T + (np.asarray(body.center_m, float) - self.origin)
        F = np.ascontiguousarray(body.faces, dtype=np.uint32)
        if body.vertex_albedo is not None:
            albedo = {"type": "mesh_attribute", "name": "vertex_albedo"}
        else:
            albedo = self._albedo_texture(body)
        props = mi.Properties()
        props["bsdf"] = mi.load_dict(bsdf_dict(body.law, albedo)) if bsdf is None else bsdf
        has_uv, has_n = body.vertex_uv is not None, body.vertex_normals is not None
        mesh = mi.Mesh(key, len(V), len(F), props=props, has_vertex_normals=has_n, has_vertex_texcoords=has_uv)
        params = mi.traverse(mesh)
        params["vertex_positions"] = type(params["vertex_positions"])(_aligned_f32(V))
        params["faces"] = type(params["faces"])(F.ravel())
        if has_n:  # smooth shading: body-frame unit normals rotated into the render frame
            params["vertex_normals"] = type(params["vertex_normals"])(
                _aligned_f32(np.asarray(body.vertex_normals, np.float64) @ body.R_render_from_body.T))
        if has_uv:
            params["vertex_texcoords"] = type(params["vertex_texcoords"])(_aligned_f32(body.vertex_uv))
        if body.vertex_albedo is not None:
            va = np.asarray(body.vertex_albedo, np.float64) * float(body.albedo)
            mesh.add_attribute("vertex_albedo", 1, type(params["vertex_positions"])(_aligned_f32(va)))
        params.update()
        return mesh

    def _shape_dict(self, body: BodySpec) -> dict:
        mi = self.mi
        R, c = body.R_render_from_body, np.asarray(body.center_m, float) - self.origin
        if body.shape == "sphere":
            d = {"type": "sphere", "to_world": mi.ScalarTransform4f(_transform4(R, c, body.radius_m))}
        elif body.shape == "box":
            d = {"type": "cube", "to_world": mi.ScalarTransform4f(_transform4(R, c, np.asarray(body.size_m) / 2))}
        elif body.shape == "plane":
            sx, sy = body.size_m
            d = {"type": "rectangle", "to_world": mi.ScalarTransform4f(_transform4(R, c, [sx / 2, sy / 2, 1.0]))}
        else:  # validated upstream (mesh files arrive as trimesh bodies)
            raise ValueError(body.shape)
        d["bsdf"] = bsdf_dict(body.law, self._albedo_texture(body))
        return d

    # ---------------------------------------------------------------- per frame
    def _set_sun(self, frame: FrameSpec) -> None:
        """Per frame, before any ray: the tiles in view (when the scene has tiled surfaces), then the sun."""
        for surf, whole in self._tiled:  # what the frame's manifest records for it (renderlab.contracts.tiled),
            surf.traced_whole = whole  # set per frame: two backends may share a plan's surfaces
        if self._tiles is not None:
            self._tiles.update(frame)
        mi = self.mi
        s = np.asarray(frame.sun.direction_render, float)
        s = s / np.linalg.norm(s)
        up = [0.0, 0.0, 1.0] if abs(s[2]) < 0.9 else [1.0, 0.0, 0.0]
        self.params["sun.to_world"] = mi.ScalarTransform4f().look_at(origin=[0, 0, 0], target=(-s).tolist(), up=up)
        self.params["sun.irradiance.value"] = float(frame.sun.irradiance_w_m2)
        self.params.update()

    def _truth_aovs(self, frame: FrameSpec, hits):
        """Position (N, 3) float32 (render origin added back in float64), normal (N, 3) float32, float64 range and body
        id from centre-ray hits (valid, P (3, N), N (3, N), registry id); NaN / −1 where nothing was hit
        (:mod:`renderlab.render.truth_aovs`)."""
        valid, P, N, reg = hits
        return truth_aovs(valid, P, N, reg, self._id_lut, np.asarray(frame.pose.position_m, float) - self.origin,
                          self.origin)

    def _camera_rays(self, camera) -> CameraRays:
        """The ray generator of ``camera`` (its float64 direction grid is built and uploaded once)."""
        cr = getattr(self, "_cam_rays", None)
        grid = self.ray_path == "drjit_grid"
        if cr is None or cr.camera != camera or cr.use_grid != grid:
            cr = self._cam_rays = CameraRays(self.mi, self.dr, camera, grid=grid)
        return cr

    def _radiance_pass(self, cr: CameraRays, pose: FramePose, shift, j0: int, m: int, seed: int):
        """Per-pixel sums of samples j0 … j0+m−1 of every pixel (shift None: one sample at each centre)."""
        mi, dr = self.mi, self.dr
        n = cr.W * cr.H * m
        idx = dr.arange(mi.UInt32, n)
        pix = idx // m
        if shift is None:
            d = cr.centre_directions(pix)
        else:
            d = cr.sample_directions(pix, cr.offsets(pix, idx - pix * m + dr.opaque(mi.UInt32, j0), shift))
        sampler = mi.load_dict({"type": "independent"})
        sampler.seed(dr.opaque(mi.UInt32, seed), n)
        spec = self._sample(sampler, cr.world_rays(d, pose))
        return dr.block_sum(spec, m) if m > 1 else spec

    def _render_drjit(self, frame: FrameSpec, seed: int) -> RenderedFrame:
        """Rays from Dr.Jit arithmetic in the kernel; the truth AOVs and the first radiance pass in one eval."""
        mi, dr = self.mi, self.dr
        cam = frame.camera
        W, H = cam.width, cam.height
        self._set_sun(frame)
        cr = self._camera_rays(cam)
        pose = FramePose(mi, dr, frame.pose.rotation.as_matrix(),
                         np.asarray(frame.pose.position_m, float) - self.origin,
                         self.settings.near_clip_m, self.settings.far_clip_m)
        si = self._hit(cr.world_rays(cr.centre_directions(dr.arange(mi.UInt32, W * H)), pose))  # coherent mode
        truth = [si.is_valid(), si.p, si.sh_frame.n, dr.reinterpret_array(mi.UInt32, si.shape)]
        ss = np.random.SeedSequence(seed)
        if self.settings.pixel_filter == "center":
            shift, passes = None, [1]
        else:  # the per-pixel Cranley-Patterson shifts of the numpy path (same draw)
            shift = mi.Float(aligned_f32(np.random.default_rng(ss.spawn(1)[0]).random((W * H, 2))))
            passes = pass_sizes(self.settings.spp, W * H, self.samples_per_pass)
        seeds = ss.generate_state(len(passes), dtype=np.uint32)
        channels = 3 if self.rgb else 1
        acc = np.zeros((channels, W * H))
        for k, m in enumerate(passes):
            total = self._radiance_pass(cr, pose, shift, sum(passes[:k]), m, int(seeds[k]))
            dr.eval(total, *(truth if k == 0 else ()))  # the truth AOVs with the first pass
            acc += np.array(total, dtype=np.float64).reshape(channels, W * H)
        valid, P, N, reg = (np.array(truth[0], dtype=bool), np.array(truth[1]), np.array(truth[2]),
                            np.array(truth[3], dtype=np.int64))
        return self._frame(frame, acc / sum(passes), (valid, P, N, reg))

    def render(self, frame: FrameSpec, seed: int) -> RenderedFrame:
        """Render one frame. ``seed`` fixes the sub-pixel pattern and Mitsuba's sampler.

        JIT variants generate the rays in the kernel (:mod:`renderlab.render.mitsuba_rays`) unless
        ``ray_path = "numpy"``; ``"drjit_grid"`` sends pinholes through the direction grid as before commit
        7018b77 (:class:`~renderlab.render.mitsuba_rays.CameraRays`, to re-make truth sets rendered then);
        scalar variants always take the numpy path. ``$RENDERLAB_MITSUBA_RAYS`` sets the default.
        """
        _check_ray_path(self.ray_path)
        if self.scalar or self.ray_path == "numpy":
            return self._render_numpy(frame, seed)
        return self._render_drjit(frame, seed)

    def _frame(self, frame: FrameSpec, radiance: np.ndarray, hits) -> RenderedFrame:
        """The RenderedFrame of mean radiance (channels, N) and centre-ray hits (valid, P, N, registry id)."""
        W, H = frame.camera.width, frame.camera.height
        P, N, rng_m, ids = self._truth_aovs(frame, hits)
        radiance = radiance.astype(np.float32)
        if self.rgb and self.mono_out:
            radiance = radiance.mean(axis=0, keepdims=True)
        radiance = radiance[0].reshape(H, W) if len(radiance) == 1 else radiance.T.reshape(H, W, 3)
        return RenderedFrame(
            radiance=radiance,
            position=P.reshape(H, W, 3),
            normal=N.reshape(H, W, 3),
            range_m=rng_m.reshape(H, W),
            body_id=ids.reshape(H, W),
        )


@contextlib.contextmanager
def tile_design(design: str):
    """``MitsubaBackend.tile_design = design`` inside the block, restored after (a backend made inside keeps the
    design it was made with: the benchmarks' and tests' side-by-side backends)."""
    old, MitsubaBackend.tile_design = MitsubaBackend.tile_design, design
    try:
        yield
    finally:
        MitsubaBackend.tile_design = old
