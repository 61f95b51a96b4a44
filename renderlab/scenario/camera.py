"""Scenario section ``[camera]``: the camera model (intrinsics in pixels, distortion). Light: pydantic only."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from renderlab.config_types import Finite, Positive
from renderlab.config_types import Strict as _Strict

class CameraConfig(_Strict):
    """Intrinsics in pixels (pixel centres are integers, (0, 0) is the top-left pixel's centre)."""

    width: Annotated[int, Field(gt=0, le=16384)] = 256
    height: Annotated[int, Field(gt=0, le=16384)] = 192
    fx: Positive = 300.0
    fy: Positive = 300.0
    cx: Finite = 127.5
    cy: Finite = 95.5
    skew: Finite = 0.0
    skew_yx: Finite = 0.0
    model: Literal["pinhole", "brown", "owen"] = "pinhole"
    distortion: dict[str, Finite] = {}
