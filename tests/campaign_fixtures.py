"""The tiny campaign the campaign-engine tests share (test helper, not part of renderlab): the analytic
sphere-and-box scene at 64×48, 4 spp, one frame, with every perturbation on, and a table comparison that leaves the
timing columns out."""

from __future__ import annotations

from pathlib import Path

from renderlab.contracts.schemas import TIMING_COLUMNS

REPO = Path(__file__).resolve().parents[1]
SCENE = REPO / "scenes" / "analytic_sphere_box.toml"
TINY = ["camera.width=64", "camera.height=48", "camera.fx=66", "camera.fy=65", "camera.cx=32", "camera.cy=23",
        "render.spp=4", "trajectory.frames=1", "perturbations.position_sigma_m=[0.1,0.1,0.1]",
        "perturbations.attitude_sigma_deg=0.5", "perturbations.focal_length_sigma_frac=0.01",
        "perturbations.principal_point_sigma_px=0.3", "perturbations.sun_direction_sigma_deg=2"]


def tables_equal(a, b) -> bool:
    """Same rows and values, timing columns excluded."""
    keep = [c for c in a.column_names if c not in TIMING_COLUMNS]
    return a.column_names == b.column_names and a.select(keep).equals(b.select(keep))
