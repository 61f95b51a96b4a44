"""Scenario section ``[sun]``: the sun as a directional source, or taken per frame from SPICE kernels. Light:
pydantic only."""

from __future__ import annotations

import math
from typing import Literal

from pydantic import Field, model_validator

from renderlab.contracts.config_types import Positive, Vec3
from renderlab.contracts.config_types import Strict as _Strict

__all__ = ["SunConfig"]


class SunConfig(_Strict):
    """The sun as a directional source. ``direction`` points from the scene *toward* the sun.

    ``source = "spice"`` (world ``analytic`` with ``trajectory.kind = "spice"``) takes the sun of every frame from the
    trajectory's kernels instead (:func:`renderlab.trajectory_io.spice.read_spice_sun`, with
    ``trajectory.aberration``): the direction from the trajectory's ``center`` toward the Sun in its ``frame``, and
    the irradiance ``irradiance_w_m2 × (1 AU / distance)²`` (``irradiance_w_m2`` is then the value at 1 AU);
    ``direction`` is not used.
    """

    source: Literal["direction", "spice"] = Field("direction", description="direction: the constant [sun] "
                                                  "direction; spice: the Sun from the trajectory's SPICE kernels, "
                                                  "per frame (analytic world, trajectory.kind = \"spice\")")
    direction: Vec3 = Field([0.3, -0.4, 0.8], description="Direction from the scene toward the sun, render "
                            "frame (any non-zero length); source = \"direction\" only")
    irradiance_w_m2: Positive = Field(1361.0, description="Solar irradiance at the scene (source = \"spice\": at "
                                      "1 AU, scaled by the inverse square of the kernels' sun distance) [W/m²]")

    @model_validator(mode="after")
    def _nonzero(self):
        if math.hypot(*self.direction) < 1e-12:
            raise ValueError("sun direction must be a non-zero vector")
        return self
