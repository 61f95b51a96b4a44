"""Scenario files: TOML in ``scenes/`` → a validated :class:`Scenario`.

A scenario holds everything needed to reproduce a truth set: the world (bodies, photometric laws,
albedo), the sun, the camera model, the trajectory, the sensor and the renderer settings.
Validation is strict: unknown keys, wrong types, non-finite or impossible values are refused with
one line that names the key (``camera.fx: Input should be greater than 0 (got -5.0)``).

``--set KEY=VALUE`` overrides any key before validation; VALUE is parsed as a TOML value
(``--set camera.width=128``, ``--set sun.direction=[1,0,1]``, ``--set render.variant="scalar_mono"``),
and a bare word that is not valid TOML is taken as a string.
"""

from __future__ import annotations

import copy
import math
import tomllib
from pathlib import Path
from typing import Annotated, Any, Literal

import pydantic
from pydantic import ConfigDict, Discriminator, Field, Tag, field_validator, model_validator

from renderlab.scenario.camera import CameraConfig, resolve_camera
from renderlab.scenario.campaign import CampaignConfig, PerturbationConfig
from renderlab.scenario.sun import SunConfig
from renderlab.scenario.trajectory import SOURCE_KINDS, SourceTrajectoryConfig, TrajectoryConfig
from renderlab.contracts.config_types import Finite, Positive, Strict as _Strict, Vec3
from renderlab.errors import UserError
from renderlab.worlds.earth.config import EarthWorld, LEOTrajectory
from renderlab.worlds.ev5.config import EV5DescentTrajectory, EV5World
from renderlab.worlds.microsat.config import MicrosatWorld, SeparationTrajectory

LAW_NAMES = ("lambert", "lommel_seeliger", "mcewen", "hapke")


class BodyConfig(_Strict):
    """One body: an analytic primitive or a triangle mesh, with a photometric law and an albedo."""

    name: str = Field(min_length=1, description="Body name, unique (the id AOV and the manifest name it)")
    shape: Literal["sphere", "box", "plane", "mesh"] = Field(description="Analytic primitive or triangle mesh")
    center_m: Vec3 = Field([0.0, 0.0, 0.0], description="Centre of the body frame, render frame [m]")
    rotation_deg: Vec3 = Field([0.0, 0.0, 0.0], description="xyz Euler angles of the body frame "
                               "(Rotation.from_euler('xyz')) [deg]")
    radius_m: Positive | None = Field(None, description="sphere: radius [m]")
    size_m: list[Positive] | None = Field(None, description="box: full extents x, y, z; plane: x, y [m]")
    file: str | None = Field(None, description="mesh: OBJ, PLY, STL or GLB (renderlab.render.mesh_io), relative to "
                             "the scenario file")
    units: Literal["m", "km", "cm"] | None = Field(None, description="mesh: length unit of the file (default m)")
    normals: Literal["flat", "smooth"] | None = Field(None, description="mesh: facet or area-weighted vertex normals "
                                                      "(default flat)")
    law: Literal["lambert", "lommel_seeliger", "mcewen", "hapke"] = Field("lambert", description="Photometric law")
    law_params: dict[str, Finite] = Field({}, description="Parameters of the law by name (mcewen, hapke: fields of "
                                          "renderlab.photometry.McEwenParams / HapkeParams; angles in rad)")
    albedo: Annotated[float, Field(ge=0, le=1, allow_inf_nan=False)] = Field(0.3, description="Albedo of the law")
    albedo_map: str | None = Field(None, description="Image file (relative to the scenario file) that scales albedo "
                                   "over the body's texture coordinates")

    @model_validator(mode="after")
    def _shape_fields(self):
        need = {"sphere": "radius_m", "box": "size_m", "plane": "size_m", "mesh": "file"}[self.shape]
        if getattr(self, need) is None:
            raise ValueError(f"shape '{self.shape}' needs '{need}'")
        if self.shape == "box" and len(self.size_m) != 3:
            raise ValueError("box size_m needs 3 values [x, y, z]")
        if self.shape == "plane" and len(self.size_m) != 2:
            raise ValueError("plane size_m needs 2 values [x, y]")
        if self.shape != "mesh" and (self.units is not None or self.normals is not None):
            raise ValueError("'units' and 'normals' apply to shape 'mesh' only")
        return self


class AnalyticWorld(_Strict):
    """Analytic world: spheres, boxes, planes and triangle meshes with photometric laws (render frame)."""

    kind: Literal["analytic"] = Field("analytic", description="World kind: bodies listed in [[world.bodies]]")
    bodies: list[BodyConfig] = Field(min_length=1, description="The bodies of the scene ([[world.bodies]]), "
                                     "names unique")

    @model_validator(mode="after")
    def _unique_names(self):
        names = [b.name for b in self.bodies]
        if len(set(names)) != len(names):
            raise ValueError(f"body names must be unique, got {names}")
        return self


class RenderConfig(_Strict):
    """Renderer settings: backend, Mitsuba variant, samples, bounces, clipping and the render seed."""

    renderer: str = Field("mitsuba", description="Render backend: a registered renderer (mitsuba, cycles, or a "
                          "plug-in's, entry-point group renderlab.renderers)")
    variant: Literal["llvm_ad_mono", "llvm_ad_rgb", "scalar_rgb", "cuda_ad_mono", "cuda_ad_rgb"] = Field(
        "llvm_ad_mono", description="Mitsuba variant (mono: one radiance channel Y; rgb: R, G, B)")
    spp: Annotated[int, Field(gt=0, le=65536)] = Field(16, description="Samples per pixel")
    max_depth: Annotated[int, Field(ge=2, le=64)] = Field(2, description="Longest light path in bounces; 2 = direct "
                                                          "sunlight only (single bounce)")
    pixel_filter: Literal["box", "center"] = Field("box", description="Pixel footprint: box = samples spread over "
                                                   "the pixel; center = one sample at the pixel centre (validation)")
    shadows: bool = Field(True, description="Cast shadows (false: every surface facing the sun is lit, shadow rays "
                          "off; needs max_depth = 2)")
    near_clip_m: Positive = Field(1e-3, description="Near clip distance [m]")
    far_clip_m: Positive = Field(1e7, description="Far clip distance, above near_clip_m [m]")
    seed: Annotated[int, Field(ge=0)] = Field(0, description="Seed of the sample pattern and the sensor noise")
    exr_compression: Literal["zip", "rle", "none"] = Field(
        "zip", description="Lossless compression of the truth EXR files: zip (smallest), rle or none (faster writes "
        "for in-the-loop and scratch sets; the pixels are the same)")

    @field_validator("renderer")
    @classmethod
    def _registered_renderer(cls, name: str) -> str:
        from renderlab import plugins

        if name not in plugins.renderers:
            raise ValueError(str(plugins.renderers.unknown(name)))
        return name

    @model_validator(mode="after")
    def _clips(self):
        if self.far_clip_m <= self.near_clip_m:
            raise ValueError(f"far_clip_m ({self.far_clip_m}) must exceed near_clip_m ({self.near_clip_m})")
        if not self.shadows and self.max_depth != 2:
            raise ValueError(f"shadows = false needs max_depth = 2 (direct sunlight), got max_depth {self.max_depth}")
        return self


class SensorConfig(_Strict):
    """Sensor settings; keys other than ``auto_exposure`` are :class:`renderlab.sensor.model.SensorOptions` fields."""

    model_config = ConfigDict(extra="allow", allow_inf_nan=False)
    auto_exposure: bool | Literal["per_frame"] = Field(True, description="Exposure chosen so the brightest pixels "
        "reach auto_exposure_fraction of full scale: on a truth set's first frame and kept (true), or for every frame "
        "from its own radiance (per_frame); false: sensor.exposure_s. Each frame records its saturated pixels")
    auto_exposure_fraction: Annotated[float, Field(gt=0, le=1)] = Field(0.8, description="Target of the "
                                                                        "auto-exposure, fraction of full scale")

    def options_dict(self) -> dict[str, Any]:
        return dict(self.model_extra or {})

    @model_validator(mode="after")
    def _known_fields(self):
        from renderlab.sensor.model import SensorOptions  # light: numpy/scipy only

        extra = self.options_dict()
        known = set(SensorOptions.__dataclass_fields__)
        unknown = sorted(set(extra) - known)
        if unknown:
            raise ValueError(f"unknown sensor key '{unknown[0]}'; expected one of {', '.join(sorted(known))}")
        for key, value in extra.items():
            if key == "noise_stream":
                if not isinstance(value, str) or value not in ("per_pixel", "sequential"):
                    raise ValueError(f"sensor.noise_stream must be 'per_pixel' or 'sequential', got {value!r}")
            elif isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ValueError(f"sensor.{key} must be a finite number, got {value!r}")
        SensorOptions(**extra)  # raises UserError naming the field
        return self


def _kind_of(default: str):
    def pick(value: Any) -> str:
        kind = value.get("kind", default) if isinstance(value, dict) else getattr(value, "kind", default)
        return f"kind={kind}"
    return pick


#: world kind → the trajectory kinds that make sense for it (the first is its default); the file kinds (``table``,
#: ``ccsds``, ``spice``) drive every world, each in its own frame (SourceTrajectoryConfig, docs/scenario_keys.md)
WORLD_TRAJECTORIES = {
    "analytic": ("line", "orbit", *SOURCE_KINDS),
    "ev5": ("ev5_descent", *SOURCE_KINDS),
    "earth": ("leo", *SOURCE_KINDS),
    "microsat": ("separation", *SOURCE_KINDS),
}

World = Annotated[
    Annotated[AnalyticWorld, Tag("kind=analytic")] | Annotated[EV5World, Tag("kind=ev5")]
    | Annotated[EarthWorld, Tag("kind=earth")] | Annotated[MicrosatWorld, Tag("kind=microsat")],
    Discriminator(_kind_of("analytic"), custom_error_type="world_kind",
                  custom_error_message=f"kind must be one of {', '.join(WORLD_TRAJECTORIES)}"),
]
_TRAJ_TAGS = {"line": "kind=line", "orbit": "kind=orbit"}
Trajectory = Annotated[
    Annotated[TrajectoryConfig, Tag("kind=line")] | Annotated[TrajectoryConfig, Tag("kind=orbit")]
    | Annotated[SourceTrajectoryConfig, Tag("kind=table")] | Annotated[SourceTrajectoryConfig, Tag("kind=ccsds")]
    | Annotated[SourceTrajectoryConfig, Tag("kind=spice")]
    | Annotated[EV5DescentTrajectory, Tag("kind=ev5_descent")] | Annotated[LEOTrajectory, Tag("kind=leo")]
    | Annotated[SeparationTrajectory, Tag("kind=separation")],
    Discriminator(_kind_of("orbit"), custom_error_type="trajectory_kind",
                  custom_error_message="kind must be one of "
                  + ", ".join(dict.fromkeys(k for ks in WORLD_TRAJECTORIES.values() for k in ks))),
]


class Scenario(_Strict):
    """A validated scenario: the core sections. Study sections (``[coastline]``, ``[unknown_satellite]``, a
    plug-in's own) are registered in :data:`renderlab.plugins.scenario_sections` and added as optional fields
    by :func:`scenario_model`; :func:`scenario_from_dict` validates with that model."""

    name: str = Field("scenario", description="Scenario name (truth-set manifest, campaign and report titles)")
    description: str = Field("", description="One line on what the scenario shows (renderlab scenes lists it)")
    world: World = Field(description="The world: [world] with its kind (analytic, ev5, earth, microsat)")
    sun: SunConfig = Field(SunConfig(), description="The sun, a directional source ([sun])")
    camera: CameraConfig = Field(CameraConfig(), description="The camera model ([camera])")
    trajectory: Trajectory = Field(TrajectoryConfig(), description="The camera path ([trajectory]) with its kind")
    sensor: SensorConfig = Field(SensorConfig(), description="The sensor ([sensor]; renderlab.sensor.model.SensorOptions "
                                 "keys)")
    render: RenderConfig = Field(RenderConfig(), description="Renderer settings ([render])")
    perturbations: PerturbationConfig = Field(PerturbationConfig(), description="Monte Carlo dispersions of a "
                                              "campaign run ([perturbations])")
    campaign: CampaignConfig = Field(CampaignConfig(), description="What a campaign runs ([campaign])")

    @model_validator(mode="before")
    @classmethod
    def _one_field_of_view(cls, data: Any) -> Any:
        """The Earth orbit's older ``trajectory.fov_deg`` moves into the camera (refused when it disagrees)."""
        from renderlab.worlds.earth.config import leo_camera

        return leo_camera(data) if isinstance(data, dict) else data

    @model_validator(mode="after")
    def _world_fits_trajectory(self):
        from renderlab.scenario.kinds import DEFAULT_POINTING, world_trajectories

        allowed = WORLD_TRAJECTORIES.get(self.world.kind) or world_trajectories()[self.world.kind]
        if self.trajectory.kind not in allowed:
            raise ValueError(f"trajectory.kind '{self.trajectory.kind}' does not fit world.kind '{self.world.kind}' "
                             f"(use {' or '.join(repr(k) for k in allowed)})")
        traj = self.trajectory
        if (traj.kind in SOURCE_KINDS and traj.attitude == "file" and not traj.reads_attitude()
                and self.world.kind not in DEFAULT_POINTING):
            raise ValueError(f"trajectory: {traj.missing_attitude()}; world.kind '{self.world.kind}' has no default "
                             "pointing")
        if self.sun.source == "spice" and (self.world.kind != "analytic" or traj.kind != "spice"):
            raise ValueError(f"sun.source = \"spice\" needs world.kind 'analytic' and trajectory.kind 'spice' (got "
                             f"'{self.world.kind}' / '{traj.kind}'; the other worlds have their own sun)")
        return self

    def to_dict(self) -> dict[str, Any]:
        """The validated scenario as plain JSON-able data (what the manifest stores)."""
        return self.model_dump(mode="json")


def scenario_model() -> type[Scenario]:
    """:class:`Scenario` with one optional field per registered study section (built once per registry state)."""
    from renderlab import plugins

    names = tuple(plugins.scenario_sections.names())
    worlds = tuple(plugins.worlds.names())
    if _MODEL_CACHE.get("names") != (names, worlds):
        fields = {n: (cls | None, Field(None, description=f"Study section [{n}] (optional): "
                                        f"{(cls.__doc__ or n).strip().splitlines()[0].rstrip('.')}"))
                  for n, cls in ((n, plugins.scenario_sections.get(n)) for n in names)}
        if set(worlds) != set(WORLD_TRAJECTORIES):  # a plug-in world: [world] and [trajectory] from the registry
            from renderlab.scenario.kinds import registered_kinds, trajectory_union, world_union

            kinds = registered_kinds()
            fields["world"] = (world_union(kinds), Field(description=Scenario.model_fields["world"].description))
            fields["trajectory"] = (trajectory_union(kinds), Field(TrajectoryConfig(),
                                    description=Scenario.model_fields["trajectory"].description))
        names = (names, worlds)
        _MODEL_CACHE["names"] = names
        _MODEL_CACHE["model"] = pydantic.create_model("Scenario", __base__=Scenario, **fields)
    return _MODEL_CACHE["model"]


_MODEL_CACHE: dict[str, Any] = {}


def truth_dict(sc_dict: dict[str, Any]) -> dict[str, Any]:
    """A scenario dict without its campaign-only sections (``perturbations``, ``campaign`` and every registered
    study section): what a truth render depends on (and what the truth cache is keyed by)."""
    import json

    from renderlab import plugins

    d = json.loads(json.dumps(sc_dict))
    for key in ("perturbations", "campaign", *plugins.scenario_sections.names()):
        d.pop(key, None)
    return d


def _format_error(err: pydantic.ValidationError, source: str) -> str:
    e = err.errors()[0]
    loc = ".".join(str(p) for p in e["loc"] if not str(p).startswith(("function-", "kind=")))
    msg = e["msg"].removeprefix("Value error, ")
    if e["type"] == "extra_forbidden":  # "did you mean": the closest field of the model at that location
        import difflib
        import typing

        def models(tp):
            if isinstance(tp, type) and issubclass(tp, pydantic.BaseModel):
                return [tp]
            return [m for a in typing.get_args(tp) for m in models(a)]
        found = [scenario_model()]
        for part in map(str, e["loc"][:-1]):
            if part.startswith("kind="):
                found = [m for m in found if "kind" in m.model_fields
                         and part[5:] in typing.get_args(m.model_fields["kind"].annotation)] or found
            elif not part.isdigit() and not part.startswith("function-"):
                found = [s for m in found if part in m.model_fields for s in models(m.model_fields[part].annotation)]
        close = difflib.get_close_matches(str(e["loc"][-1]), [n for m in found for n in m.model_fields], n=1,
                                          cutoff=0.7)
        return f"{source}: unknown key '{loc}'" + (f"; did you mean '{close[0]}'?" if close else "")
    if e["type"] == "missing":
        return f"{source}: missing key '{loc}'"
    got = e.get("input")
    got_txt = "" if isinstance(got, dict) or got is None else f" (got {got!r})"
    where = f"{loc}: " if loc else ""
    return f"{source}: {where}{msg}{got_txt}"


def parse_override(text: str) -> tuple[list[str], Any]:
    """Parse ``KEY=VALUE`` (dotted KEY, TOML VALUE) into (path, value)."""
    if "=" not in text:
        raise UserError(f"--set expects KEY=VALUE, got {text!r}")
    key, raw = text.split("=", 1)
    key = key.strip()
    if not key or any(not part for part in key.split(".")):
        raise UserError(f"--set has an empty key in {text!r}")
    try:
        value = tomllib.loads(f"v = {raw.strip()}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw.strip()
    return key.split("."), value


def apply_overrides(data: dict[str, Any], overrides: list[str]) -> dict[str, Any]:
    """Return a copy of ``data`` with each ``KEY=VALUE`` override applied (lists indexed by number)."""
    out = copy.deepcopy(data)
    for text in overrides:
        path, value = parse_override(text)
        node: Any = out
        for i, part in enumerate(path[:-1]):
            nxt = path[i + 1]
            if isinstance(node, list):
                if not part.isdigit() or int(part) >= len(node):
                    raise UserError(f"--set {'.'.join(path)}: no list item {part}")
                node = node[int(part)]
            else:
                node = node.setdefault(part, [] if nxt.isdigit() else {})
            if not isinstance(node, (dict, list)):
                raise UserError(f"--set {'.'.join(path)}: '{part}' is not a table")
        last = path[-1]
        if isinstance(node, list):
            if not last.isdigit() or int(last) >= len(node):
                raise UserError(f"--set {'.'.join(path)}: no list item {last}")
            node[int(last)] = value
        else:
            node[last] = value
    return out


def scenario_from_dict(data: dict[str, Any], source: str = "scenario") -> Scenario:
    """Validate plain data into a :class:`Scenario` (UserError with one line on failure)."""
    try:
        return scenario_model().model_validate(data)
    except pydantic.ValidationError as err:
        raise UserError(_format_error(err, source)) from None
    except UserError as err:
        raise UserError(f"{source}: {err}") from None


def read_toml(path: str | Path) -> dict[str, Any]:
    p = Path(path)
    if not p.is_file():
        raise UserError(f"scenario file not found: {path}")
    try:
        return tomllib.loads(p.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as err:
        raise UserError(f"{p.name}: not valid TOML ({err})") from None
    except UnicodeDecodeError:
        raise UserError(f"{p.name}: not a text file") from None


def load_scenario(path: str | Path, overrides: list[str] | None = None) -> tuple[Scenario, Path]:
    """Read, override and validate a scenario file.

    Returns
    -------
    (Scenario, Path)
        The scenario and the folder it came from (relative file references resolve against it).
    """
    p = Path(path)
    base = p.resolve().parent
    data = apply_overrides(read_toml(p), overrides or [])
    try:  # camera.calibration_file (relative to the file) and camera.fov_deg → plain intrinsics, once
        data = resolve_camera(data, base)
    except UserError as err:
        raise UserError(f"{p.name}: {err}") from None
    return scenario_from_dict(data, p.name), base
