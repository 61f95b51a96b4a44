"""The lab's built-in scenario files: package data in ``renderlab/scenes/`` (``scenes/`` of a checkout links there).

They ship in the wheel, so ``renderlab demo`` and the studies find them in any install, editable or not.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from renderlab.errors import UserError

SCENES_DIR = Path(str(resources.files("renderlab") / "scenes"))


def scene_names() -> list[str]:
    """The file names of the built-in scenarios (``*.toml``), sorted."""
    return sorted(p.name for p in SCENES_DIR.glob("*.toml"))


def scene_path(name: str) -> Path:
    """The path of built-in scenario ``name`` (e.g. ``"coastline_ekf.toml"``); UserError when it is missing."""
    path = SCENES_DIR / name
    if not path.is_file():
        known = ", ".join(scene_names()) or "none"
        raise UserError(f"built-in scenario {name} not found in {SCENES_DIR} (built-in: {known}); "
                        "reinstall renderlab (the wheel ships them as package data)")
    return path
