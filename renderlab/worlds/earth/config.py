"""Scenario sections of the Earth world (``world.kind = "earth"``) and LEO orbits
(``trajectory.kind = "leo"``). Light: pydantic only (imported when any scenario is validated)."""

from __future__ import annotations

from typing import Literal

from renderlab.config_types import Seed, Strict


class EarthWorld(Strict):
    """WGS-84 Earth with GSHHG land/water albedo, optional clouds, real sun for the epoch."""

    kind: Literal["earth"] = "earth"
    seed: Seed = 0


class LEOTrajectory(Strict):
    """A LEO orbit from classical elements, nadir-pointing camera."""

    kind: Literal["leo"] = "leo"
