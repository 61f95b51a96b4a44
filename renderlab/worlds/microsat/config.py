"""Scenario sections of the unknown-satellite world (``world.kind = "microsat"``) and its relative
motion (``trajectory.kind = "separation"``). Light: pydantic only.

Units: metres, m/s, kg·m², degrees and deg/s only where the key says so.
"""

from __future__ import annotations

import math
from typing import Annotated, Literal

from pydantic import Field, model_validator

from renderlab.contracts.config_types import Finite, Positive, Seed, Strict, Vec3

Albedo = Annotated[float, Field(ge=0, le=1, allow_inf_nan=False)]
PositiveVec3 = Annotated[list[Positive], Field(min_length=3, max_length=3)]


def _nonzero(v, name):
    if math.hypot(*v) < 1e-12:
        raise ValueError(f"{name} must be a non-zero vector")


class MicrosatTumble(Strict):
    """The target's tumble under a file trajectory (``[world.tumble]``; the ``separation`` trajectory sets it with
    its own keys): attitude and absolute body rate at trajectory time 0, propagated by Euler + gravity gradient on
    the chaser's circular orbit of ``altitude_m``. Defaults: those of the ``separation`` trajectory."""

    q0_lvlh_from_body_xyzw: Annotated[list[Finite], Field(min_length=4, max_length=4)] = Field(
        [0.2, -0.1, 0.3, 0.93], description="Target attitude at trajectory time 0 (normalised), x y z w")
    omega0_body_deg_s: Vec3 = Field([1.5, 3.6, 1.5], description="Absolute body rate of the target at trajectory "
                                    "time 0, body axes [deg/s]")
    altitude_m: Annotated[float, Field(gt=100e3, lt=50000e3, allow_inf_nan=False)] = Field(
        600e3, description="Circular orbit altitude of the chaser (mean motion, gravity gradient, the sun's turn in "
        "LVLH) [m]")
    attitude_substeps: Annotated[int, Field(ge=1, le=1000)] = Field(10, description="Attitude integration steps "
                                                                    "per frame interval")

    @model_validator(mode="after")
    def _checks(self):
        if math.hypot(*self.q0_lvlh_from_body_xyzw) < 1e-9:
            raise ValueError("q0_lvlh_from_body_xyzw must be a non-zero quaternion")
        return self


class MicrosatWorld(Strict):
    """A Chibis-M-like microsatellite: bus, two solar panels, long thin antennas whose tips carry small
    bright knobs (the reference features). Body frame = principal axes, origin at the centre of mass."""

    kind: Literal["microsat"] = Field("microsat", description="World kind: a Chibis-M-like microsatellite")
    seed: Seed = Field(0, description="Jitters the antenna directions (± antenna_jitter_deg)")
    bus_size_m: PositiveVec3 = Field([0.45, 0.45, 0.5], description="Bus box extents, body axes [m]")
    panel_size_m: Annotated[list[Positive], Field(min_length=2, max_length=2)] = Field(
        [0.45, 0.3], description="Solar panel extents [m]")
    n_antennas: Annotated[int, Field(ge=4, le=12)] = Field(6, description="Number of antennas (knob tips are the "
                                                           "reference features)")
    antenna_length_m: Positive = Field(0.8, description="Antenna length [m]")
    antenna_width_m: Positive = Field(0.012, description="Antenna width [m]")
    antenna_jitter_deg: Annotated[float, Field(ge=0, le=20, allow_inf_nan=False)] = Field(
        5.0, description="Seeded jitter of the antenna directions [deg]")
    knob_radius_m: Positive = Field(0.03, description="Radius of the bright knob at each antenna tip [m]")
    inertia_kg_m2: PositiveVec3 = Field([1.6, 2.1, 2.6], description="Principal moments of inertia (body axes), "
                                        "triangle inequality [kg·m²]")
    albedo_bus: Albedo = Field(0.12, description="Albedo of the bus")
    albedo_panel: Albedo = Field(0.05, description="Albedo of the solar panels")
    albedo_antenna: Albedo = Field(0.25, description="Albedo of the antennas")
    albedo_knob: Albedo = Field(0.9, description="Albedo of the antenna-tip knobs")
    sun_lvlh: Vec3 = Field([0.4, 0.7, 0.5], description="Toward the sun at t = 0, chaser LVLH frame (non-zero)")
    tumble: MicrosatTumble | None = Field(None, description="The target's tumble under a file trajectory "
                                          "([world.tumble]; default: the separation trajectory's defaults); the "
                                          "separation trajectory sets it with its own keys")

    @model_validator(mode="after")
    def _checks(self):
        _nonzero(self.sun_lvlh, "sun_lvlh")
        I1, I2, I3 = self.inertia_kg_m2
        if I1 + I2 < I3 or I2 + I3 < I1 or I1 + I3 < I2:
            raise ValueError(f"inertia_kg_m2 {self.inertia_kg_m2} violates the triangle inequality")
        if self.knob_radius_m * 2 >= self.antenna_length_m:
            raise ValueError("knob_radius_m must be much smaller than antenna_length_m")
        return self


class SeparationTrajectory(Strict):
    """Clohessy-Wiltshire relative motion after separation; Euler + gravity-gradient attitude.

    The chaser holds its LVLH attitude; the camera is fixed on it at ``camera_offset_lvlh_m`` from its
    centre of mass, looking along ``camera_boresight_lvlh``. The target's state at the first frame is
    ``r0_lvlh_m``, ``v0_lvlh_mps`` (relative to the chaser's centre of mass), ``q0_lvlh_from_body_xyzw`` and
    the absolute body rate ``omega0_body_deg_s``.
    """

    kind: Literal["separation"] = Field("separation", description="Trajectory kind: Clohessy-Wiltshire motion "
                                        "after separation")
    frames: Annotated[int, Field(gt=0, le=100000)] = Field(100, description="Number of frames")
    dt_s: Positive = Field(0.1, description="Time between frames [s]")
    altitude_m: Annotated[float, Field(gt=100e3, lt=50000e3, allow_inf_nan=False)] = Field(
        600e3, description="Circular orbit altitude of the chaser (mean motion, gravity gradient) [m]")
    r0_lvlh_m: Vec3 = Field([0.05, -4.6, 0.05], description="Target position at the first frame, relative to the "
                            "chaser's centre of mass, LVLH [m]")
    v0_lvlh_mps: Vec3 = Field([0.01, -0.12, 0.005], description="Target velocity at the first frame, LVLH [m/s]")
    q0_lvlh_from_body_xyzw: Annotated[list[Finite], Field(min_length=4, max_length=4)] = Field(
        [0.2, -0.1, 0.3, 0.93], description="Target attitude at the first frame (normalised), x y z w")
    omega0_body_deg_s: Vec3 = Field([1.5, 3.6, 1.5], description="Absolute body rate of the target at the first "
                                    "frame, body axes [deg/s]")
    camera_offset_lvlh_m: Vec3 = Field([0.0, -0.6, 0.0], description="Camera position on the chaser from its "
                                       "centre of mass, LVLH [m]")
    camera_boresight_lvlh: Vec3 = Field([0.0, -1.0, 0.0], description="Camera boresight, LVLH (non-zero)")
    camera_up_lvlh: Vec3 = Field([1.0, 0.0, 0.0], description="Toward the top of the image, LVLH (non-zero)")
    attitude_substeps: Annotated[int, Field(ge=1, le=1000)] = Field(10, description="Attitude integration steps "
                                                                    "per frame interval")

    @model_validator(mode="after")
    def _checks(self):
        _nonzero(self.camera_boresight_lvlh, "camera_boresight_lvlh")
        _nonzero(self.camera_up_lvlh, "camera_up_lvlh")
        if math.hypot(*self.q0_lvlh_from_body_xyzw) < 1e-9:
            raise ValueError("q0_lvlh_from_body_xyzw must be a non-zero quaternion")
        return self
