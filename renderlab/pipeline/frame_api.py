"""The warm frame API: open a scenario's world once, then pose in → image and truth out, in memory.

:class:`Renderer` is the one render path of the lab: ``renderlab render`` (:func:`renderlab.pipeline.write_frames`),
campaigns and their truth-perturbed runs (:mod:`renderlab.campaign.cache`) and the studies render through it, so a
frame asked for here equals, byte for byte, the frame a truth set holds for the same scenario, seed and pose
(``tests/test_frame_api.py``). Use::

    from renderlab import Renderer

    with Renderer("scenes/ev5_descent.toml", overrides=["camera.width=256"]) as r:
        for k in range(r.n_frames):
            f = r.frame(k, pose=my_pose(k))   # the world at frame k, the camera where the vehicle really is
            f.dn, f.radiance, f.aovs.range_m, f.truth["landmark_truth"], f.meta

**World state and camera.** ``frame(index)`` renders the world as planned at frame ``index`` (its time, sun,
bodies) from the planned camera; ``frame(time_s=t, pose=p)`` the world at any time t of the trajectory's clock (EV5:
the sun turned with the spin from the nearest planned frame; a world that cannot say refuses with one line); ``pose=`` puts the camera elsewhere (any convention of
:func:`renderlab.pipeline.poses.camera_pose`, in the world's render frame: ``r.render_frame``), ``sun=``,
``camera=`` and ``spp=`` override the sun (a :class:`SunSpec` or a unit vector toward the sun), the camera model
and the samples per pixel for that frame. A world whose scene is built around each planned pose (Earth: a local
tangent tile per footprint) declares ``scene_follows_pose`` and refuses a moved camera with one line.

**Seeds.** Frame ``index`` uses the ``index``-th child of the scenario's ``render.seed`` (as ``renderlab render``
spawns them), split into the sample pattern and the sensor noise; ``seed=`` gives another root. The sensor noise
is keyed per pixel (:mod:`renderlab.sensor.model`), so two frames that differ in a few radiance pixels differ in those DN.

**Exposure.** With ``sensor.auto_exposure = true`` the exposure time is chosen on the first frame with DN (of a
truth set, or since this renderer was made or :meth:`Renderer.reset_exposure`) and kept, like a camera whose
exposure is set once per sequence (:func:`renderlab.sensor.model.exposure_for_peak`: a high percentile of the mean charge
at ``auto_exposure_fraction`` of full scale); ``"per_frame"`` chooses it for every frame from its own radiance;
``false`` uses ``sensor.exposure_s``; ``exposure_s=`` fixes it for one frame. Every frame's record carries its exposure
and its count of saturated pixels (``sensor.saturated_px``), and a truth set warns about frames over 1 % saturated.
To re-make frame k of a truth set alone, pass its manifest exposure (``exposure_s=``) or render frame 0 first.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from renderlab.errors import UserError
from renderlab.geometry.rotations import quat_xyzw
from renderlab.render.scene import FrameSpec, RenderedFrame, SunSpec

#: what :meth:`Renderer.frame` can return
OUTPUTS = ("dn", "radiance", "truth")
#: first spawn-key word of frames asked for at a time (planned frame k uses spawn key (k,))
TIME_SPAWN_KEY = 2**32 - 1


@dataclass
class Frame:
    """One rendered frame, in memory.

    Attributes
    ----------
    index : int
        The world state's frame index.
    spec : FrameSpec
        Camera model, pose (render frame) and sun the frame was rendered with.
    radiance : ndarray (H, W) float32 or None
        Band radiance, W m⁻² sr⁻¹ (box-filtered over each pixel).
    dn : ndarray (H, W) uint16 or None
        The sensor image, DN.
    aovs : RenderedFrame or None
        Truth AOVs at the pixel centres: ``position`` (render frame, m), ``normal``, ``range_m`` (m, float64),
        ``body_id`` (−1 where nothing was hit).
    truth : dict
        The world's truth rows of this frame (``{"landmark_truth": [...]}`` for EV5, ``coastline_truth`` for
        Earth, ``feature_truth`` for the microsatellite): the rows ``renderlab render`` writes as Parquet.
    meta : dict
        The frame's manifest record (camera, pose, sun, bodies, world metadata, sensor).
    exposure_s : float
        Exposure time used for ``dn`` (s); NaN when no DN was made.
    saturated_px : int
        Pixels at full well or at the ADC maximum (−1 when no DN was made).
    """

    index: int
    spec: FrameSpec
    radiance: np.ndarray | None = None
    dn: np.ndarray | None = None
    aovs: RenderedFrame | None = None
    truth: dict = field(default_factory=dict)
    meta: dict = field(default_factory=dict)
    exposure_s: float = float("nan")
    saturated_px: int = -1

    @property
    def time_s(self) -> float:
        return float(self.spec.pose.time_s)


def _load(scenario, base_dir, overrides, seed):
    """(Scenario, base folder) from a path or a Scenario, with ``--set`` overrides and a seed."""
    from renderlab.scenario import Scenario, load_scenario

    if isinstance(scenario, (str, Path)):
        sc, base = load_scenario(Path(scenario), list(overrides))
    elif isinstance(scenario, Scenario):
        sc = scenario
        if overrides:
            from renderlab.scenario import apply_overrides, scenario_from_dict

            sc = scenario_from_dict(apply_overrides(scenario.to_dict(), list(overrides)), "overrides")
        base = Path(base_dir) if base_dir is not None else Path(".")
    else:
        raise UserError(f"Renderer needs a scenario file or a Scenario, got {type(scenario).__name__}")
    if seed is not None:
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise UserError(f"seed must be a non-negative integer, got {str(seed)[:40]}")
        sc = sc.model_copy(update={"render": sc.render.model_copy(update={"seed": int(seed)})})
    return sc, (Path(base_dir) if base_dir is not None else base)


class Renderer:
    """A scenario's world, built once, and its renderer, loaded once: frames in memory (module docstring).

    Parameters
    ----------
    scenario : str, Path or Scenario
        A scenario file (validated, ``overrides`` applied) or a loaded :class:`~renderlab.scenario.Scenario`.
    base_dir : path, optional
        Folder that relative file paths of the scenario resolve against (default: the scenario file's folder).
    overrides : sequence of str
        ``KEY=VALUE`` overrides, as ``--set``.
    seed : int, optional
        Root seed (default ``render.seed``).
    renderer : str, optional
        A registered renderer (default ``render.renderer``).
    """

    def __init__(self, scenario, base_dir=None, *, overrides=(), seed=None, renderer: str | None = None):
        from renderlab import plugins
        from renderlab.sensor.model import SensorOptions
        from renderlab.worlds.base import make_plan

        self.scenario, self.base_dir = _load(scenario, base_dir, overrides, seed)
        self.renderer_name = renderer or self.scenario.render.renderer
        plugins.renderers.get(self.renderer_name, where="render.renderer: ")  # a wrong name: one line, now
        self.options = SensorOptions(**self.scenario.sensor.options_dict())
        self.plan = make_plan(self.scenario, self.base_dir)
        self._by_index = {s.index: k for k, s in enumerate(self.plan.frames)}
        self._key, self.scene, self.backend, self.loads = object(), None, None, 0
        self._locked_exposure: float | None = None  # auto_exposure = true: the first frame's

    # ------------------------------------------------------------------ the world
    @property
    def n_frames(self) -> int:
        """Planned frames of the world (its trajectory's states)."""
        return len(self.plan.frames)

    @property
    def render_frame(self) -> dict:
        """The frame poses are given in (``{"name": "EV5_FIXED"}``, ...)."""
        return self.plan.render_frame

    def backend_for(self, spec: FrameSpec):
        """(backend, scene) for ``spec``; the scene is loaded only when the plan's scene key changes."""
        from renderlab.pipeline.backend import make_backend

        key = self.plan.scene_key(spec)
        if self.backend is None or key != self._key:
            self.scene = self.plan.scene(key)
            self.backend, self._key = make_backend(self.scenario, self.scene, self.renderer_name), key
            self.loads += 1
        return self.backend, self.scene

    def seed_for(self, index: int, root: int | None = None) -> np.random.SeedSequence:
        """Frame ``index``'s seed: the child ``renderlab render`` spawns for it (a fresh ``SeedSequence``)."""
        k = self._by_index.get(int(index), int(index))
        return np.random.SeedSequence(int(self.scenario.render.seed if root is None else root), spawn_key=(k,))

    def spec(self, index: int = 0, *, pose=None, sun=None, camera=None) -> FrameSpec:
        """The frame spec of world state ``index`` with the camera at ``pose`` (module docstring)."""
        from renderlab.pipeline.poses import camera_pose

        if isinstance(index, bool) or not isinstance(index, (int, np.integer)) or int(index) not in self._by_index:
            raise UserError(f"frame index must be one of the world's {self.n_frames} frames "
                            f"(0..{self.n_frames - 1}), got {str(index)[:40]}")
        planned = self.plan.frames[self._by_index[int(index)]]
        spec = planned
        if pose is not None:
            if getattr(self.plan, "scene_follows_pose", False):
                raise UserError(f"world '{self.scenario.world.kind}' builds its scene around each planned pose; "
                                "it cannot move the camera (render its planned frames, or fly a file trajectory)")
            p = camera_pose(pose, time_s=float(planned.pose.time_s))
            if p.epoch_utc is None and planned.pose.epoch_utc is not None:
                p = dataclasses.replace(p, epoch_utc=planned.pose.epoch_utc)
            spec = dataclasses.replace(spec, pose=p)
        return _override(spec, sun, camera)

    def spec_at(self, time_s: float, pose, *, sun=None, camera=None) -> FrameSpec:
        """The frame spec of the world at time ``time_s`` (s, the trajectory's clock) from ``pose``
        (:meth:`WorldPlan.spec_at <renderlab.worlds.base.WorldPlan.spec_at>`: EV5 turns the sun with the spin)."""
        from renderlab.pipeline.poses import camera_pose

        t = _finite(time_s, "time_s")
        p = dataclasses.replace(camera_pose(pose, time_s=t), time_s=t)
        return _override(self.plan.spec_at(t, p), sun, camera)

    # ------------------------------------------------------------------ frames
    def reset_exposure(self) -> None:
        """With ``sensor.auto_exposure = true``: the next frame with DN chooses the exposure again."""
        self._locked_exposure = None

    def frame(self, index: int | None = None, *, time_s: float | None = None, pose=None, sun=None, camera=None,
              spp: int | None = None, outputs=OUTPUTS, seed: int | None = None,
              exposure_s: float | None = None) -> Frame:
        """Render world state ``index`` (default 0) from ``pose`` (default: the planned camera), or the world at
        ``time_s`` from ``pose``, into memory.

        ``outputs`` is any subset of ``("dn", "radiance", "truth")``; nothing is written to disk. A frame at
        ``time_s`` is seeded by its time (microseconds), so the same time and pose give the same bytes in any order.
        """
        outputs = _outputs(outputs)
        if time_s is None:
            spec = self.spec(0 if index is None else index, pose=pose, sun=sun, camera=camera)
            ss = self.seed_for(spec.index, seed)
        else:
            if index is not None or pose is None:
                raise UserError("a frame at time_s needs a pose and no index")
            spec = self.spec_at(time_s, pose, sun=sun, camera=camera)
            root = int(self.scenario.render.seed if seed is None else seed)
            ss = np.random.SeedSequence(root, spawn_key=(TIME_SPAWN_KEY, int(round(spec.pose.time_s * 1e6)) % 2**63))
        return self.render_spec(spec, ss, outputs=outputs, spp=spp, exposure_s=exposure_s)

    def render_spec(self, spec: FrameSpec, seed: np.random.SeedSequence, *, outputs=OUTPUTS,
                    spp: int | None = None, exposure_s: float | None = None) -> Frame:
        """Render one frame spec with its seed (the loop every truth set goes through)."""
        from renderlab.sensor.model import exposure_for_peak, expose, with_exposure
        from renderlab.files.signals import raise_pending

        raise_pending()  # a signal whose raise the garbage collector swallowed ends the loop here
        backend, scene = self.backend_for(spec)
        render_ss, sensor_ss = seed.spawn(2)
        rendered = _render(backend, spec, int(render_ss.generate_state(1)[0]), spp)
        out = Frame(index=int(spec.index), spec=spec)
        if "radiance" in outputs:
            out.radiance = rendered.radiance
        if "dn" in outputs:
            lum = rendered.radiance if rendered.radiance.ndim == 2 else rendered.radiance.mean(-1)  # mono sensor
            opts = self.options
            if exposure_s is not None:
                opts = with_exposure(opts, _exposure(exposure_s))
            elif self.scenario.sensor.auto_exposure:
                mode = self.scenario.sensor.auto_exposure
                if mode == "per_frame" or self._locked_exposure is None:  # from this frame's own radiance
                    t = exposure_for_peak(lum, opts, fraction=self.scenario.sensor.auto_exposure_fraction)
                    self._locked_exposure = self._locked_exposure if mode == "per_frame" else t
                opts = with_exposure(opts, t if mode == "per_frame" else self._locked_exposure)
            sensor = expose(lum, opts, np.random.default_rng(sensor_ss))
            out.dn, out.exposure_s = sensor.dn, float(opts.exposure_s)
            out.saturated_px = int(np.count_nonzero(sensor.saturated))
            out.meta = frame_meta(spec, self.plan, scene, opts)
            out.meta["sensor"]["saturated_px"] = out.saturated_px
        else:
            out.meta = frame_meta(spec, self.plan, scene, None)
        if "truth" in outputs:
            out.aovs = rendered
            out.truth = self.plan.frame_rows(spec, rendered)
        return out

    def close(self) -> None:
        """Drop the loaded scene and renderer (the world plan stays)."""
        self.backend = self.scene = None
        self._key = object()

    def __enter__(self) -> "Renderer":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _override(spec: FrameSpec, sun, camera) -> FrameSpec:
    """``spec`` with the sun and the camera model replaced where given."""
    if sun is not None:
        spec = dataclasses.replace(spec, sun=_sun(sun, spec.sun))
    if camera is not None:
        from renderlab.geometry.camera import CameraModel

        if not isinstance(camera, CameraModel):
            raise UserError(f"camera must be a renderlab CameraModel, got {type(camera).__name__}")
        spec = dataclasses.replace(spec, camera=camera)
    return spec


def _finite(value, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) or \
            not np.isfinite(value) or abs(value) > 1e12:
        raise UserError(f"{name} must be a finite number of seconds (|t| <= 1e12), got {str(value)[:40]}")
    return float(value)


def _exposure(value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating)) or not np.isfinite(value) \
            or not 0 < value <= 3600:
        raise UserError(f"exposure_s must be a number of seconds in (0, 3600], got {str(value)[:40]}")
    return float(value)


def _outputs(outputs) -> tuple:
    if isinstance(outputs, str):
        outputs = (outputs,)
    bad = [str(o)[:40] for o in outputs if o not in OUTPUTS]
    if bad or not outputs:
        raise UserError(f"outputs must be a non-empty subset of {', '.join(OUTPUTS)}, got {bad or 'nothing'}")
    return tuple(outputs)


def _sun(sun, planned: SunSpec) -> SunSpec:
    if isinstance(sun, SunSpec):
        d, e = np.asarray(sun.direction_render, float), float(sun.irradiance_w_m2)
    else:
        d, e = np.asarray(sun, dtype=float), float(planned.irradiance_w_m2)
    if d.shape != (3,) or not np.all(np.isfinite(d)) or np.linalg.norm(d) < 1e-12 or not np.isfinite(e) or e < 0:
        raise UserError("sun must be a SunSpec or a finite non-zero 3-vector toward the sun (render frame)")
    return SunSpec(direction_render=d / np.linalg.norm(d), irradiance_w_m2=e)


def _render(backend, spec: FrameSpec, seed: int, spp: int | None) -> RenderedFrame:
    """``backend.render`` with an optional per-frame spp (backends that take it: ``per_frame_spp``)."""
    if spp is None or spp == backend.settings.spp:
        return backend.render(spec, seed=seed)
    if isinstance(spp, bool) or not isinstance(spp, (int, np.integer)) or not 0 < spp <= 65536:
        raise UserError(f"spp must be an integer in 1..65536, got {str(spp)[:40]}")
    if not getattr(backend, "per_frame_spp", False):
        raise UserError(f"renderer '{backend.name}' takes spp only when loaded (set render.spp)")
    settings = backend.settings
    backend.settings = dataclasses.replace(settings, spp=int(spp))
    try:
        return backend.render(spec, seed=seed)
    finally:
        backend.settings = settings


def frame_meta(spec: FrameSpec, plan, scene, opts) -> dict:
    """A frame's manifest record: camera, pose (render frame), Sun, the plan's metadata, the sensor settings."""
    meta = {
        "camera": spec.camera.to_dict(),
        "pose": {
            "position_m": [float(v) for v in spec.pose.position_m],
            "quat_render_from_cam_xyzw": [float(v) for v in quat_xyzw(spec.pose.rotation)],
        },
        "sun": spec.sun.to_dict(),
        **plan.frame_meta(spec, scene),
    }
    if opts is not None:
        meta["sensor"] = {"exposure_s": float(opts.exposure_s), "bits": int(opts.bits),
                          "gain_e_per_dn": float(opts.gain_e_per_dn), "bias_dn": float(opts.bias_dn),
                          "noise_stream": str(opts.noise_stream)}
    return meta
