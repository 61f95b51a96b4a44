"""The lab's built-in scenario files (``scenes/`` of the checkout)."""

from __future__ import annotations

from pathlib import Path

from renderlab.errors import UserError

SCENES_DIR = Path(__file__).resolve().parents[1] / "scenes"


def scene_path(name: str) -> Path:
    """The path of built-in scenario ``name`` (e.g. ``"coastline_ekf.toml"``); UserError when it is missing."""
    path = SCENES_DIR / name
    if not path.is_file():
        raise UserError(f"built-in scenario {name} not found in {SCENES_DIR} (install with ./setup.sh from a checkout)")
    return path
