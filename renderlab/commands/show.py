"""``renderlab show SCENARIO [--set KEY=VALUE ...]``: the resolved, validated scenario as TOML.

SCENARIO is a file or a built-in name (``renderlab scenes``). The scenario is read, overridden and validated as
``renderlab render`` does (:func:`renderlab.commands.cost.load_checked`), then printed: keys the file, a ``--set`` or the
loader gave (``camera.fov_deg`` and ``camera.calibration_file`` become ``fx, fy, cx, cy``) as keys; keys left at
their default commented out (``# key = value``), as are the tables that were left out. Uncommented, a default reads
the same; left commented, validators that care which keys were given (``trajectory.target_m`` only with
``attitude = "look_at"``) see the input they saw. ``tomllib.loads`` of the output validates to the same scenario.

:func:`dumps` is a small TOML writer for plain data: tables, arrays of tables, inline values, ``None`` left
out, floats by ``repr``; :class:`Default` marks a value to write commented out.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from typing import Any

from renderlab.commands.cost import load_checked


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("show", help="print a scenario's resolved, validated configuration as TOML")
    p.add_argument("scenario", metavar="SCENARIO", help="scenario TOML file or built-in name (see renderlab scenes)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", dest="overrides",
                   help="override a scenario key (TOML value), e.g. --set camera.width=128; repeatable")
    p.add_argument("--no-defaults", action="store_true", help="leave out the keys at their default")


@dataclass(frozen=True)
class Default:
    """A value left at its default: :func:`dumps` writes it commented out."""

    value: Any


def annotate(model) -> dict:
    """A validated pydantic model as plain data: sub-models as tables (lists of them as arrays of tables),
    other values as ``model_dump(mode="json")`` gives them, wrapped in :class:`Default` where the field was not
    given."""
    from pydantic import BaseModel

    dumped = model.model_dump(mode="json")
    given = model.model_fields_set | set(model.model_extra or {})
    out: dict[str, Any] = {}
    for name in [*type(model).model_fields, *(model.model_extra or {})]:
        value = getattr(model, name)
        if isinstance(value, BaseModel):
            out[name] = annotate(value) if name in given else Default(annotate(value))
        elif isinstance(value, list) and value and all(isinstance(v, BaseModel) for v in value):
            items = [annotate(v) for v in value]
            out[name] = items if name in given else Default(items)
        else:
            out[name] = dumped[name] if name in given else Default(dumped[name])
    return out


def _strip_defaults(data: dict) -> dict:
    out = {}
    for k, v in data.items():
        if isinstance(v, Default):
            continue
        if isinstance(v, dict):  # a table that was given stays, even when all its keys are defaults
            v = _strip_defaults(v)
        elif isinstance(v, list) and v and all(isinstance(x, dict) for x in v):
            v = [_strip_defaults(x) for x in v]
        out[k] = v
    return out


def _is_table_array(v: Any) -> bool:
    return isinstance(v, list) and bool(v) and all(isinstance(x, dict) for x in v)


def _header(path: tuple[str, ...]) -> str:
    from renderlab.scenario.keyref import toml_key

    return ".".join(toml_key(p) for p in path)


def _emit(d: dict, path: tuple[str, ...], lines: list[str], comment: bool) -> None:
    """Write the keys of table ``d`` (at ``path``), then its sub-tables and arrays of tables."""
    from renderlab.scenario.keyref import toml_key, toml_value

    later = []
    for key, v in d.items():
        default = isinstance(v, Default)
        raw = v.value if default else v
        if raw is None:
            continue
        if isinstance(raw, dict) and raw:
            later.append((key, raw, comment or default, False))
        elif _is_table_array(raw):
            later.append((key, raw, comment or default, True))
        else:
            lines.append(f"{'# ' if comment or default else ''}{toml_key(key)} = {toml_value(raw)}")
    for key, raw, commented, array in later:
        mark = "# " if commented else ""
        for item in (raw if array else [raw]):
            lines.append("")
            lines.append(f"{mark}[[{_header((*path, key))}]]" if array else f"{mark}[{_header((*path, key))}]")
            _emit(item, (*path, key), lines, commented)


def dumps(data: dict) -> str:
    """``data`` (str keys; dict, list, str, int, float, bool, None, :class:`Default` values) as TOML text."""
    lines: list[str] = []
    _emit(data, (), lines, False)
    return "\n".join(lines).lstrip("\n") + "\n"


def scenario_toml(scenario, *, defaults: bool = True, header: list[str] = ()) -> str:
    """A validated scenario as TOML (module docstring); ``header`` lines become leading comments."""
    data = annotate(scenario)
    if not defaults:
        data = _strip_defaults(data)
    return "".join(f"# {h}\n" for h in header) + ("\n" if header else "") + dumps(data)


def run(args) -> int:
    from renderlab import __version__
    from renderlab.commands.scenes import scenario_file

    path = scenario_file(args.scenario)
    scenario, base = load_checked(path, args.overrides)
    command = " ".join(["renderlab show", str(args.scenario), *(f"--set {o}" for o in args.overrides)])
    header = [command,
              f"The resolved, validated scenario (renderlab {__version__})"
              + ("; keys at their default are commented out." if not args.no_defaults else "; defaults left out."),
              f"Relative file paths in it resolve against {base}."]
    sys.stdout.write(scenario_toml(scenario, defaults=not args.no_defaults, header=header))
    return 0
