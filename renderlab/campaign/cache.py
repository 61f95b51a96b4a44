"""Truth renders cached per (scene, pose): re-run estimators without re-rendering.

A truth set is fully determined by its validated scenario (world, camera, pose/trajectory, sun, sensor,
render settings including the seed) and the number of frames. Its cache key is the SHA-256 of that
canonical JSON plus the truth-set format; the set lives in ``<cache_root>/<key>/`` and is written
atomically by :class:`renderlab.truthset.TruthSetWriter`, so concurrent workers rendering the same key
both end with one complete set.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

from renderlab.errors import UserError


def truth_key(scenario_dict: dict, frames: int | None = None) -> str:
    """Cache key of a render: hash of the scenario data (which includes camera pose and seed)."""
    from renderlab.truthset import FORMAT

    text = json.dumps({"format": FORMAT, "scenario": scenario_dict, "frames": frames},
                      sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:24]


def _complete(path: Path) -> bool:
    return (path / "manifest.json").is_file()


def cached_truthset(scenario, base_dir: Path, cache_root: Path, *, frames: int | None = None) -> tuple[Path, bool]:
    """Path of the truth set of ``scenario`` (rendered now if not cached) and whether it was a hit."""
    from renderlab.render.pipeline import render_truthset

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
