"""Shared fixtures: tiny scenes rendered by the real Mitsuba backend, and independent numpy oracles."""

from __future__ import annotations

import copy
import os
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))

# One OpenBLAS thread per test process (set before numpy is imported; inherited by the xdist workers and the children
# tests start). The tier runs 2 workers on 2 cores, and each worker's second BLAS thread waits on the other's: 400
# 27x27 solves took 9.3 s with OpenBLAS's default 2 threads and 0.02 s with 1 (busy machine). Results change only by
# rounding (the re-makes of published rows, compared to 1e-9, pass). A value the user set is kept.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

REPO = Path(__file__).resolve().parents[1]

BASE_SCENARIO = {
    "name": "test",
    "world": {
        "kind": "analytic",
        "bodies": [
            {"name": "ground", "shape": "plane", "center_m": [0, 0, 0], "size_m": [20, 20], "law": "lambert", "albedo": 0.25},
            {"name": "sphere", "shape": "sphere", "center_m": [-0.5, 0.4, 1.0], "radius_m": 1.0, "law": "lambert",
             "albedo": 0.5},
        ],
    },
    "sun": {"direction": [0.5, -0.3, 0.8], "irradiance_w_m2": 1361.0},
    "camera": {"width": 64, "height": 48, "fx": 70.0, "fy": 64.0, "cx": 33.7, "cy": 21.2},
    "trajectory": {"kind": "line", "frames": 1, "start_m": [0.5, -7.0, 4.5], "target_m": [0, 0, 0.6]},
    "render": {"spp": 4, "seed": 1, "near_clip_m": 0.01, "far_clip_m": 1000.0},
    "sensor": {"auto_exposure": True},
}


def scenario_dict(**sections):
    """BASE_SCENARIO with top-level sections replaced/merged (dicts merge one level deep)."""
    d = copy.deepcopy(BASE_SCENARIO)
    for key, value in sections.items():
        if isinstance(value, dict) and isinstance(d.get(key), dict):
            d[key].update(value)
        else:
            d[key] = value
    return d


def render_one(d: dict, seed: int = 1, frame: int = 0):
    """Render one frame of a scenario dict with the real Mitsuba backend → (RenderedFrame, FrameSpec)."""
    from renderlab.pipeline import frame_specs, make_backend
    from renderlab.scenario import scenario_from_dict
    from renderlab.worlds.analytic import build_scene

    sc = scenario_from_dict(d)
    scene = build_scene(sc.world, REPO / "scenes")
    backend = make_backend(sc, scene, "mitsuba")
    spec = frame_specs(sc)[frame]
    return backend.render(spec, seed=seed), spec


@pytest.fixture(scope="session")
def repo() -> Path:
    return REPO
