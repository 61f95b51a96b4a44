"""Truth renders cached per (scene, pose): re-run estimators without re-rendering.

A truth set is fully determined by its validated scenario (world, camera, pose/trajectory, sun, sensor,
render settings including the seed) and the number of frames. Its cache key is the SHA-256 of that
canonical JSON plus the truth-set format and a fingerprint of the code that makes truth (the sources of
``renderlab.render``, ``worlds``, ``geometry``, ``dynamics``, the sensor, photometry, truth-set and scenario
modules, and the installed Mitsuba/Dr.Jit/bpy versions), so a render cached by older truth code is never
reused after that code changes, and the content hashes of the files it references (albedo maps, meshes,
shape models: a changed file is a new key even under the same name); the set lives in ``<cache_root>/<key>/`` and is written
atomically by :class:`renderlab.files.truthset.TruthSetWriter`, so concurrent workers rendering the same key
both end with one complete set.

Runs whose *true* poses differ (truth trajectory/pointing perturbations) render their own frames:
:func:`cached_frames_truthset` keys a render by the scenario **and the content of its frame specs** (index,
time, position, attitude quaternion, camera, Sun of every frame, :func:`frame_record`), so a re-run, or
another method on the same run, finds it. Those renders use one :class:`~renderlab.pipeline.frame_api.Renderer`
per process (the world plan built once, the renderer's scene loaded once and reused for every pose: only the sensor pose
changes between calls), and the per-frame render seeds of :func:`renderlab.pipeline.render_truthset`
(frame k of the plan: the k-th child of ``SeedSequence(render.seed)``), so the nominal poses give the
nominal truth set's images.
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
from importlib import metadata
from pathlib import Path

from renderlab.errors import UserError
from renderlab.files.truthset import FORMAT
from renderlab.geometry.rotations import quat_xyzw
from renderlab.inputs import LIMITS, sha256
from renderlab.pipeline import render_truthset, write_frames
from renderlab.pipeline.frame_api import Renderer
from renderlab.render.mitsuba_backend import MitsubaBackend

_TRUTH_PACKAGES = ("render", "worlds", "geometry", "dynamics", "scenario", "pipeline")
_TRUTH_MODULES = ("sensor/model.py", "sensor/noise.py", "photometry.py", "files/truthset.py", "files/imageio.py",
                  "contracts/config_types.py")
_RENDERER_DISTS = ("mitsuba", "drjit", "bpy")


def fingerprint_truth_sources(root: Path) -> str:
    """SHA-256 (hex, 16 chars) of the truth-side sources under the package folder ``root`` and of the
    renderer versions installed (estimator, campaign and report code is left out: it does not change truth)."""
    root = Path(root)
    files = [root / m for m in _TRUTH_MODULES]
    for pkg in _TRUTH_PACKAGES:
        files += [f for f in (root / pkg).rglob("*") if f.suffix in (".py", ".osl") and f.is_file()]
    h = hashlib.sha256()
    for f in sorted(set(files)):
        if f.is_file():
            h.update(f.relative_to(root).as_posix().encode() + b"\0" + f.read_bytes() + b"\0")
    for dist in _RENDERER_DISTS:
        try:
            h.update(f"{dist}={metadata.version(dist)}".encode())
        except metadata.PackageNotFoundError:
            h.update(f"{dist}=none".encode())
    return h.hexdigest()[:16]


@functools.lru_cache(maxsize=None)
def truth_code_fingerprint() -> str:
    """:func:`fingerprint_truth_sources` of this installation of renderlab (computed once per process)."""
    return fingerprint_truth_sources(Path(__file__).resolve().parents[1])


#: scenario keys that name files (relative to the scenario's folder), besides any ``*_file``/``*_map``/``*_path``
FILE_KEYS = ("file", "albedo_map", "shape_file", "calibration_file", "oem", "aem", "kernels")
_FILE_SUFFIXES = ("_file", "_files", "_map", "_path")


def referenced_files(data, where: str = "") -> list[tuple[str, str]]:
    """``(dotted key, path text)`` of every file a scenario dict names (:data:`FILE_KEYS` and keys ending in
    ``_file``, ``_map``, ``_path``; lists of paths too), in key order."""
    out = []
    items = data.items() if isinstance(data, dict) else enumerate(data) if isinstance(data, list) else ()
    for k, v in items:
        key = f"{where}.{k}" if where else str(k)
        named = isinstance(k, str) and (k in FILE_KEYS or k.endswith(_FILE_SUFFIXES))
        if named and isinstance(v, str) and v:
            out.append((key, v))
        elif named and isinstance(v, list) and v and all(isinstance(x, str) for x in v):
            out += [(f"{key}.{i}", x) for i, x in enumerate(v) if x]
        elif isinstance(v, (dict, list)):
            out += referenced_files(v, key)
    return out


def file_sha256(path: Path) -> str:
    """``sha256:<hex>`` of a file's content (read in 1 MiB blocks), or ``missing``/``unreadable``."""
    if not os.path.lexists(path):
        return "missing"
    return sha256(path, "scenario file", LIMITS["hashed"])  # a regular file (no FIFO, no device), else UserError


def file_hashes(scenario_dict: dict, base_dir) -> dict[str, str]:
    """``{dotted key: sha256 of the content}`` of every file the scenario references (resolved against
    ``base_dir``, the scenario's folder): what ``--resume`` and the truth cache compare, not the names."""
    return {key: file_sha256(Path(base_dir) / rel) for key, rel in referenced_files(scenario_dict)}


def render_path_options() -> dict:
    """The process-wide Mitsuba render-path choices that change a render's pixels but are not scenario keys
    (``MitsubaBackend.ray_path``, e.g. ``$RENDERLAB_MITSUBA_RAYS=drjit_grid``; ``MitsubaBackend.integrator``;
    ``MitsubaBackend.tile_design``),
    where they differ from the defaults: part of :func:`truth_key`, so a truth set rendered with another ray path
    or integrator is never served from the cache for the default one (keys of default renders are unchanged)."""
    out = {}
    if MitsubaBackend.ray_path != "drjit":
        out["mitsuba_ray_path"] = MitsubaBackend.ray_path
    if MitsubaBackend.integrator != "auto":
        out["mitsuba_integrator"] = MitsubaBackend.integrator
    if MitsubaBackend.tile_design != "auto":
        out["mitsuba_tile_design"] = MitsubaBackend.tile_design
    return out


def truth_key(scenario_dict: dict, frames: int | None = None, files: dict | None = None,
              frame_records: list | None = None) -> str:
    """Cache key of a render: hash of the scenario data (which includes camera pose and seed), the frame
    count, the truth-set format, :func:`truth_code_fingerprint`, :func:`render_path_options`, the content hashes
    of the files the scenario references (``files``, from :func:`file_hashes`; left out when there are none), and, for a
    render of given frames (:func:`cached_frames_truthset`), their :func:`frame_record` contents."""
    key = {"format": FORMAT, "scenario": scenario_dict, "frames": frames, "code": truth_code_fingerprint()}
    key.update(render_path_options())
    if files:
        key["files"] = files
    if frame_records is not None:
        key["frame_specs"] = frame_records
    text = json.dumps(key, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:24]


def _complete(path: Path) -> bool:
    return (path / "manifest.json").is_file()


def cached_truthset(scenario, base_dir: Path, cache_root: Path, *, frames: int | None = None) -> tuple[Path, bool]:
    """Path of the truth set of ``scenario`` (rendered now if not cached) and whether it was a hit."""
    data = scenario.to_dict()
    key = truth_key(data, frames, file_hashes(data, base_dir))
    path = Path(cache_root) / key
    if _complete(path):
        return path, True
    try:
        render_truthset(scenario, base_dir, path, frames=frames, progress=False, overwrite=False)
    except UserError:
        if _complete(path):  # another worker finished the same render first
            return path, True
        raise
    return path, False


# ------------------------------------------------------------------ renders of given frame specs (perturbed truth)
def frame_record(spec) -> dict:
    """The content of one frame spec (what the renderer sees of it), JSON-able with exact floats."""
    return {"index": int(spec.index), "time_s": float(spec.pose.time_s),
            "position_m": [float(v) for v in spec.pose.position_m],
            "quat_render_from_cam_xyzw": [float(v) for v in quat_xyzw(spec.pose.rotation)],
            "camera": spec.camera.to_dict(), "sun": spec.sun.to_dict()}


_WORLDS: dict = {}  # this process's loaded world (one at a time: worlds are large)


def loaded_world(scenario, base_dir: Path):
    """This process's :class:`~renderlab.pipeline.frame_api.Renderer` of ``scenario`` (world plan built and scene
    loaded on first use, kept for later runs)."""
    data = scenario.to_dict()
    key = truth_key(data, None, file_hashes(data, base_dir))
    if key not in _WORLDS:
        _WORLDS.clear()
        _WORLDS[key] = Renderer(scenario, Path(base_dir))
    return _WORLDS[key]


def cached_frames_truthset(scenario, base_dir: Path, cache_root: Path, specs: list, *,
                           note: dict | None = None) -> tuple[Path, bool]:
    """Path of the truth set of ``scenario`` rendered at the frame specs ``specs`` (e.g. perturbed true
    poses; rendered now if not cached, keyed by :func:`frame_record` of each) and whether it was a hit.
    ``note`` (JSON-able) goes into the manifest as ``frame_specs_note`` (e.g. the perturbation drawn)."""
    data = scenario.to_dict()
    key = truth_key(data, None, file_hashes(data, base_dir), [frame_record(s) for s in specs])
    path = Path(cache_root) / key
    if _complete(path):
        return path, True
    try:
        render_frames(loaded_world(scenario, base_dir), path, specs, note=note)
    except UserError:
        if _complete(path):  # another worker finished the same render first
            return path, True
        raise
    return path, False


def render_frames(world, out_dir: Path, specs: list, *, note: dict | None = None) -> Path:
    """Render ``specs`` from ``world`` into a truth set at ``out_dir`` (written atomically) by the render loop of
    :func:`renderlab.pipeline.render_truthset` (:func:`renderlab.pipeline.write_frames`: same seeds,
    auto-exposure on the first frame, sensor, files, the plan's metadata and truth tables) with the world's
    loaded renderer."""
    sc, plan = world.scenario, world.plan
    head = {"scenario": sc.to_dict(), "seed": int(sc.render.seed), "render_frame": plan.render_frame,
            "frame_specs_note": note or {}}
    seeds = [world.seed_for(spec.index) for spec in specs]
    return write_frames(out_dir, world, specs, seeds, head=head)
