"""Scenario sections of the EV5 world (``world.kind = "ev5"``) and its descent (``trajectory.kind =
"ev5_descent"``). Light: pydantic only (imported when any scenario is validated)."""

from __future__ import annotations

from typing import Literal

from renderlab.config_types import Seed, Strict


class EV5World(Strict):
    """Procedural 2008 EV5 (or a user's shape model) with a high-resolution landing site."""

    kind: Literal["ev5"] = "ev5"
    seed: Seed = 0  # the same seed makes the same body, site, catalog and maplets


class EV5DescentTrajectory(Strict):
    """Hold point → 1 km → 200 m waypoint → 50 m (spin matched) → surface over the landing site."""

    kind: Literal["ev5_descent"] = "ev5_descent"
