"""Truth renders cached per (scene, pose): re-run estimators without re-rendering.

A truth set is fully determined by its validated scenario (world, camera, pose/trajectory, sun, sensor,
render settings including the seed) and the number of frames. Its cache key is the SHA-256 of that
canonical JSON plus the truth-set format and a fingerprint of the code that makes truth (the sources of
``renderlab.render``, ``worlds``, ``geometry``, ``dynamics``, the sensor, photometry, truth-set and scenario
modules, and the installed Mitsuba/Dr.Jit/bpy versions), so a render cached by older truth code is never
reused after that code changes; the set lives in ``<cache_root>/<key>/`` and is written
atomically by :class:`renderlab.truthset.TruthSetWriter`, so concurrent workers rendering the same key
both end with one complete set.
"""

from __future__ import annotations

import functools
import hashlib
import json
from importlib import metadata
from pathlib import Path

from renderlab.errors import UserError


_TRUTH_PACKAGES = ("render", "worlds", "geometry", "dynamics", "scenario")
_TRUTH_MODULES = ("sensor.py", "photometry.py", "truthset.py", "imageio.py", "pipeline.py", "config_types.py")
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


def truth_key(scenario_dict: dict, frames: int | None = None) -> str:
    """Cache key of a render: hash of the scenario data (which includes camera pose and seed), the frame
    count, the truth-set format and :func:`truth_code_fingerprint`."""
    from renderlab.truthset import FORMAT

    text = json.dumps({"format": FORMAT, "scenario": scenario_dict, "frames": frames,
                       "code": truth_code_fingerprint()}, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:24]


def _complete(path: Path) -> bool:
    return (path / "manifest.json").is_file()


def cached_truthset(scenario, base_dir: Path, cache_root: Path, *, frames: int | None = None) -> tuple[Path, bool]:
    """Path of the truth set of ``scenario`` (rendered now if not cached) and whether it was a hit."""
    from renderlab.pipeline import render_truthset

    key = truth_key(scenario.to_dict(), frames)
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
