"""Scenario sections of the unknown-satellite world (``world.kind = "microsat"``) and its relative
motion (``trajectory.kind = "separation"``). Light: pydantic only."""

from __future__ import annotations

from typing import Literal

from renderlab.config_types import Seed, Strict


class MicrosatWorld(Strict):
    """A Chibis-M-like microsatellite: bus, panels, long thin antennas (tips = reference features)."""

    kind: Literal["microsat"] = "microsat"
    seed: Seed = 0


class SeparationTrajectory(Strict):
    """Clohessy-Wiltshire relative motion after separation; Euler + gravity-gradient attitude."""

    kind: Literal["separation"] = "separation"
