"""The world contract: a world kind is its scenario ``[world]`` model, the trajectory kinds that fit it (each with its
``[trajectory]`` model) and the function that turns a validated scenario into a
:class:`renderlab.worlds.base.WorldPlan` (frames and scenes).

A plug-in world (the Moon, a comet, a space station) registers a :class:`WorldKind` under the entry-point group
``renderlab.worlds``; the scenario schema is built from the registry, so ``[world] kind = "moon"`` validates with the
plug-in's own model and no lab file is edited. Model classes and functions may be given as ``"module:attr"`` strings
(imported on first use, so registration stays light).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

from renderlab.contracts.refs import load


@dataclass(frozen=True)
class WorldKind:
    """A registered world kind.

    Attributes
    ----------
    kind : str
        The ``world.kind`` value.
    config : type or str
        Pydantic model of the ``[world]`` section (its ``kind`` field a ``Literal`` of ``kind``).
    trajectories : dict
        Trajectory kind → pydantic model of the ``[trajectory]`` section (or ``"module:attr"``); the first is the
        world's default trajectory kind.
    make_plan : callable or str
        ``make_plan(scenario, base_dir) -> WorldPlan``.
    """

    kind: str
    config: Any
    trajectories: dict = field(default_factory=dict)
    make_plan: Callable | str | None = None

    def plan(self, scenario, base_dir):
        return load(self.make_plan)(scenario, base_dir)
