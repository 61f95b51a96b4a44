"""Scenario section ``[trajectory]`` for camera-path trajectories (``line``, ``orbit``); the world-specific kinds
live with their worlds (``ev5_descent``, ``leo``, ``separation``). Light: pydantic only."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, model_validator

from renderlab.config_types import Finite, Positive, Vec3
from renderlab.config_types import Strict as _Strict

class TrajectoryConfig(_Strict):
    """Camera path. ``line``: from ``start_m`` to ``end_m``; ``orbit``: around ``target_m`` at
    ``range_m`` and ``elevation_deg`` from ``azimuth_start_deg`` to ``azimuth_end_deg``.
    The camera always looks at ``target_m`` with ``up`` toward the top of the image."""

    kind: Literal["line", "orbit"] = "orbit"
    frames: Annotated[int, Field(gt=0, le=100000)] = 1
    dt_s: Positive = 1.0
    target_m: Vec3 = [0.0, 0.0, 0.0]
    up: Vec3 = [0.0, 0.0, 1.0]
    start_m: Vec3 | None = None
    end_m: Vec3 | None = None
    range_m: Positive = 10.0
    elevation_deg: Annotated[float, Field(gt=-90, lt=90, allow_inf_nan=False)] = 30.0
    azimuth_start_deg: Finite = -90.0
    azimuth_end_deg: Finite = -90.0

    @model_validator(mode="after")
    def _line_fields(self):
        if self.kind == "line" and self.start_m is None:
            raise ValueError("trajectory kind 'line' needs 'start_m'")
        return self
