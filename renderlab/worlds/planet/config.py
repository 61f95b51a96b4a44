"""Scenario sections of the planet world (``world.kind = "planet"``) and its own camera path
(``trajectory.kind = "planet_approach"``). Light: pydantic only.

Presets (``world.preset``; every value can be overridden by the keys of the same name):

=======  ==========================================  ==============================  ======  ==================
preset   shape (semi-axes)                           source                          law     albedo
=======  ==========================================  ==============================  ======  ==================
moon     sphere, 1737.4 km                           IAU WGCCRE 2015 (Archinal et    mcewen  0.12
                                                     al. 2018, doi:10.1007/s10569-
                                                     017-9805-5), mean radius
mars     spheroid, 3396.19 / 3396.19 / 3376.20 km    same, mean ellipsoid            lambert 0.25 (Bond albedo)
earth    spheroid, WGS 84: 6378.137 / 6356.752 km    NIMA TR8350.2 (WGS 84)          lambert 0.15 (no clouds,
                                                                                             nominal)
ev5      2008 EV5, the ``ev5`` world's procedural     Busch et al. 2011, Icarus 212,  hapke   0.085 (C-type, as
         global shape (``ev5_seed``, ``ev5_facet_m``)  649                                     the ``ev5`` world)
custom   ``semi_axes_m`` (required)                  —                               lambert 0.3
=======  ==========================================  ==============================  ======  ==================
"""

from __future__ import annotations

import math
from typing import Annotated, Literal

from pydantic import Field, model_validator

from renderlab.contracts.config_types import Finite, Positive, Seed, Strict, Vec3

LAWS = ("lambert", "lommel_seeliger", "mcewen", "hapke")
PositiveVec3 = Annotated[list[Positive], Field(min_length=3, max_length=3)]

#: preset → (semi-axes m or None for the EV5 mesh, law, albedo)
PRESETS: dict[str, tuple[tuple[float, float, float] | None, str, float]] = {
    "moon": ((1737.4e3, 1737.4e3, 1737.4e3), "mcewen", 0.12),
    "mars": ((3396.19e3, 3396.19e3, 3376.20e3), "lambert", 0.25),
    "earth": ((6378137.0, 6378137.0, 6356752.314245), "lambert", 0.15),
    "ev5": (None, "hapke", 0.085),
    "custom": (None, "lambert", 0.3),
}


class PlanetWorld(Strict):
    """A resolved body for centre/limb navigation: a sphere or triaxial ellipsoid (or the EV5 shape) at the origin of
    the ``PLANET_FIXED`` render frame, with one photometric law (presets in the module docstring)."""

    kind: Literal["planet"] = Field("planet", description="World kind: one sphere / ellipsoid / small body")
    preset: Literal["moon", "mars", "earth", "ev5", "custom"] = Field(
        "moon", description="Body: moon (sphere), mars and earth (spheroids), ev5 (the EV5 shape from afar), "
        "custom (semi_axes_m)")
    semi_axes_m: PositiveVec3 | None = Field(None, description="Semi-axes along the body x, y, z axes (custom: "
                                             "required; else overrides the preset's; not for ev5) [m]")
    rotation_deg: Vec3 = Field([0.0, 0.0, 0.0], description="xyz Euler angles of the body axes in the render frame "
                               "(Rotation.from_euler('xyz')) [deg]")
    law: Literal["lambert", "lommel_seeliger", "mcewen", "hapke"] | None = Field(
        None, description="Photometric law (default: the preset's)")
    law_params: dict[str, Finite] = Field({}, description="Parameters of the law by name (mcewen, hapke: fields of "
                                          "renderlab.photometry.McEwenParams / HapkeParams; angles in rad)")
    albedo: Annotated[float, Field(gt=0, le=1, allow_inf_nan=False)] | None = Field(
        None, description="Albedo of the law (hapke: w; default: the preset's)")
    mesh_level: Annotated[int, Field(ge=3, le=9)] = Field(
        7, description="Icosphere level of a non-spherical ellipsoid's mesh (20·4^level facets; level 7: limb "
        "ripple ±6.7e-6 of the radius)")
    ev5_seed: Seed = Field(0, description="ev5: the world.seed of the ev5 world whose global shape is used")
    ev5_facet_m: Annotated[float, Field(ge=1.0, allow_inf_nan=False)] = Field(
        8.0, description="ev5: facet edge of the global shape [m]")
    origin_tolerance_px: Positive = Field(
        0.01, description="Largest float32 position error (in pixels at the body) allowed with the render origin at "
        "the body centre; beyond it the origin moves to where the camera looks [px]")

    @model_validator(mode="after")
    def _shape_keys(self):
        if self.preset == "custom" and self.semi_axes_m is None:
            raise ValueError("preset 'custom' needs 'semi_axes_m'")
        if self.preset == "ev5" and self.semi_axes_m is not None:
            raise ValueError("preset 'ev5' takes its shape from the ev5 world ('semi_axes_m' is for the others)")
        return self

    def resolved(self) -> tuple[tuple[float, float, float] | None, str, float]:
        """(semi-axes or None for the EV5 mesh, law, albedo) after the preset and the overrides."""
        axes, law, albedo = PRESETS[self.preset]
        if self.semi_axes_m is not None:
            axes = tuple(float(v) for v in self.semi_axes_m)
        return axes, self.law or law, float(self.albedo if self.albedo is not None else albedo)


class PlanetApproachTrajectory(Strict):
    """The planet world's own camera path: the camera at ``range`` from the body centre, on the side that makes the
    Sun–body–camera angle ``phase``, both varied linearly over the frames (approach: range; terminator sweep:
    phase). The camera plane contains the sun direction; ``phase_plane_deg`` turns it about the sun direction.
    The boresight points at the body centre, or ``offset_deg`` (x, y) away so that the centre appears off-axis
    (x toward +s, y toward +l in the image)."""

    kind: Literal["planet_approach"] = Field(description="Range and phase angle per frame, boresight on the body "
                                             "(plus offset_deg)")
    frames: Annotated[int, Field(gt=0, le=100000)] = Field(1, description="Number of frames")
    dt_s: Positive = Field(1.0, description="Time between frames [s]")
    range_start_m: Positive = Field(description="Camera to body centre at the first frame [m]")
    range_end_m: Positive | None = Field(None, description="... at the last frame (default: range_start_m) [m]")
    phase_start_deg: Annotated[float, Field(ge=0, le=179, allow_inf_nan=False)] = Field(
        0.0, description="Sun–body–camera angle at the first frame [deg]")
    phase_end_deg: Annotated[float, Field(ge=0, le=179, allow_inf_nan=False)] | None = Field(
        None, description="... at the last frame (default: phase_start_deg) [deg]")
    phase_plane_deg: Finite = Field(0.0, description="Turn of the camera's plane about the sun direction (0: the "
                                    "plane holding the sun direction and render +z) [deg]")
    offset_deg: Annotated[list[Annotated[float, Field(gt=-80, lt=80, allow_inf_nan=False)]],
                          Field(min_length=2, max_length=2)] = Field(
        [0.0, 0.0], description="Angles of the body centre from the boresight, toward +s and +l [deg]")
    up: Vec3 = Field([0.0, 0.0, 1.0], description="Render-frame direction toward the top of the image")

    @model_validator(mode="after")
    def _up(self):
        if math.hypot(*self.up) < 1e-12:
            raise ValueError("up must be a non-zero vector")
        return self
