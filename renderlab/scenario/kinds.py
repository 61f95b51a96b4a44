"""World and trajectory kinds of a scenario, built from the world registry (:data:`renderlab.plugins.worlds`):
the lab's worlds are registered here like any plug-in world (:class:`renderlab.contracts.world.WorldKind`)."""

from __future__ import annotations

from typing import Annotated, Any, Union

from pydantic import Discriminator, Tag

from renderlab.contracts.world import WorldKind, load

_PATHS = "renderlab.scenario.trajectory:"
#: the lab's camera paths (``line``, ``orbit``): a world whose plan builds its frames with
#: :func:`renderlab.worlds.base.frame_specs` may declare them
CAMERA_PATHS = {"orbit": _PATHS + "TrajectoryConfig", "line": _PATHS + "TrajectoryConfig"}
#: the trajectories read from the user's files: every lab world declares them, and so may a plug-in world whose plan
#: takes a camera path (:func:`renderlab.worlds.base.frame_specs` samples them; its frame is the file's)
FILE_TRAJECTORIES = {"table": _PATHS + "SourceTrajectoryConfig", "ccsds": _PATHS + "SourceTrajectoryConfig",
                     "spice": _PATHS + "SourceTrajectoryConfig"}
#: world kind → the pointing a file trajectory without attitude gets (other worlds need the attitude in the files)
DEFAULT_POINTING = {"earth": "nadir"}
ANALYTIC = WorldKind("analytic", "renderlab.scenario:AnalyticWorld", {**CAMERA_PATHS, **FILE_TRAJECTORIES},
                     "renderlab.worlds.analytic:make_plan")
EV5 = WorldKind("ev5", "renderlab.worlds.ev5.config:EV5World",
                {"ev5_descent": "renderlab.worlds.ev5.config:EV5DescentTrajectory", **FILE_TRAJECTORIES},
                "renderlab.worlds.ev5:make_plan")
EARTH = WorldKind("earth", "renderlab.worlds.earth.config:EarthWorld",
                  {"leo": "renderlab.worlds.earth.config:LEOTrajectory", **FILE_TRAJECTORIES},
                  "renderlab.worlds.earth:make_plan")
MICROSAT = WorldKind("microsat", "renderlab.worlds.microsat.config:MicrosatWorld",
                     {"separation": "renderlab.worlds.microsat.config:SeparationTrajectory", **FILE_TRAJECTORIES},
                     "renderlab.worlds.microsat:make_plan")
PLANET = WorldKind("planet", "renderlab.worlds.planet.config:PlanetWorld",
                   {"planet_approach": "renderlab.worlds.planet.config:PlanetApproachTrajectory", **CAMERA_PATHS,
                    **FILE_TRAJECTORIES}, "renderlab.worlds.planet:make_plan")


def _kind_of(default: str):
    def pick(value: Any) -> str:
        kind = value.get("kind", default) if isinstance(value, dict) else getattr(value, "kind", default)
        return f"kind={kind}"
    return pick


def registered_kinds() -> dict[str, WorldKind]:
    """World kind → :class:`WorldKind` from the registry (entry points included)."""
    from renderlab import plugins

    out = {}
    for name in plugins.worlds.names():
        wk = plugins.worlds.get(name)
        if not isinstance(wk, WorldKind) or wk.kind != name:
            from renderlab.errors import UserError

            raise UserError(f"world plug-in '{name}' must register a renderlab.contracts.world.WorldKind of that kind")
        out[name] = wk
    return out


def world_trajectories(kinds: dict[str, WorldKind] | None = None) -> dict[str, tuple[str, ...]]:
    """World kind → its trajectory kinds (the first is the default)."""
    kinds = registered_kinds() if kinds is None else kinds
    return {k: tuple(wk.trajectories) for k, wk in kinds.items()}


def world_union(kinds: dict[str, WorldKind]):
    """The ``world`` field type: a union discriminated on ``kind`` (default ``analytic``)."""
    members = tuple(Annotated[load(wk.config), Tag(f"kind={k}")] for k, wk in kinds.items())
    return Annotated[Union[members], Discriminator(_kind_of("analytic"), custom_error_type="world_kind",
                                                   custom_error_message=f"kind must be one of {', '.join(kinds)}")]


def trajectory_union(kinds: dict[str, WorldKind]):
    """The ``trajectory`` field type: every registered trajectory kind (default ``orbit``)."""
    members, names = [], []
    for wk in kinds.values():
        for t, model in wk.trajectories.items():
            if t not in names:
                names.append(t)
                members.append(Annotated[load(model), Tag(f"kind={t}")])
    return Annotated[Union[tuple(members)], Discriminator(_kind_of("orbit"), custom_error_type="trajectory_kind",
                                                          custom_error_message=f"kind must be one of {', '.join(names)}")]
