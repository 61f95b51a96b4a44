"""The scenario key reference, generated from the pydantic models (``docs/scenario_keys.md``).

Every key of a scenario file is a field of a model under :func:`renderlab.scenario.scenario_model` (the core
sections, one model per world and trajectory kind, and the registered study sections); its ``Field(description=
...)`` is the key's documentation, ending with its unit in brackets (``"Image width [px]"``). This module walks
those models and writes one Markdown table per section: key (dotted, as ``--set`` spells it), type, default,
allowed values or range, unit and description. The ``[sensor]`` keys are the fields of
:class:`renderlab.sensor.model.SensorOptions`, read from its docstring.

::

    python -m renderlab.scenario.keyref           # rewrite docs/scenario_keys.md
    python -m renderlab.scenario.keyref --check   # exit 1 if docs/scenario_keys.md is stale
    python -m renderlab.scenario.keyref --stdout  # print it

``tests/test_keyref.py`` fails when the committed file differs from a fresh generation.
"""

from __future__ import annotations

import dataclasses
import json
import re
import sys
import types
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any, Literal, Union

import annotated_types as at
from pydantic import BaseModel
from pydantic.fields import FieldInfo
from pydantic_core import PydanticUndefined

from renderlab.scenario import WORLD_TRAJECTORIES, scenario_model
from renderlab.sensor.model import SensorOptions

DOC = Path(__file__).resolve().parents[2] / "docs" / "scenario_keys.md"
REGENERATE = "python -m renderlab.scenario.keyref"
_UNIT = re.compile(r"\s*\[([^\[\]]+)\]$")
#: keys the loader reads before validation (renderlab.scenario.camera.resolve_camera): section → rows
LOADER_KEYS = {
    "camera": [("fov_deg", "float", "—", "(0, 180)", "deg",
                "Horizontal field of view over the full image width: fx = fy = (width/2) / tan(fov_deg/2), "
                "principal point at the image centre unless cx/cy are given; not with fx/fy"),
               ("calibration_file", "string", "—", "", "",
                "OpenCV (cv2.FileStorage YAML/JSON) or ROS camera_info calibration, relative to the scenario "
                "file; sets every intrinsic (width/height may be given and must match)"),
               ("calibration_model", "string", "—", "plumb_bob, radtan, brown, opencv, rational_polynomial, "
                "equidistant, fisheye, kannala_brandt, none, pinhole", "",
                "Distortion model of calibration_file: required when the file holds 4 coefficients and no fisheye "
                "flag (fisheye_model / fisheye: 1 or 0) or distortion_model of its own (OpenCV's k1 k2 p1 p2 and "
                "cv2.fisheye's k1..k4 look alike); checked against the file's flag or name when it has one")],
}
_SENSOR_UNITS = {"_e_per_s": "e⁻/s", "_e_per_dn": "e⁻/DN", "_dn": "DN", "_e": "e⁻", "_px": "px", "_m": "m",
                 "_s": "s"}


@dataclass
class Section:
    """One table of the reference: ``[path]`` with its rows (key, type, default, allowed, unit, description)."""

    title: str
    doc: str
    rows: list[tuple[str, ...]] = field(default_factory=list)


def toml_value(v: Any) -> str:
    """``v`` as a TOML value (inline tables and arrays; floats by ``repr``; strings JSON-quoted)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return {"inf": "inf", "-inf": "-inf", "nan": "nan"}.get(repr(v), repr(v))
    if isinstance(v, int):
        return str(v)
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, BaseModel):
        return toml_value(v.model_dump(mode="json", exclude_none=True))
    if isinstance(v, dict):
        items = [f"{toml_key(k)} = {toml_value(x)}" for k, x in v.items() if x is not None]
        return "{" + ", ".join(items) + "}" if items else "{}"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in v if x is not None) + "]"
    raise TypeError(f"no TOML form for {type(v).__name__}")


def toml_key(k: str) -> str:
    """A TOML key: bare when it can be, else quoted."""
    return k if re.fullmatch(r"[A-Za-z0-9_-]+", k) else json.dumps(k, ensure_ascii=False)


# ----------------------------------------------------------------------------------------- types
def _strip(tp: Any) -> tuple[Any, list]:
    """``Annotated[T, ...]`` → (T, its constraints), nested Annotated flattened."""
    meta: list = []
    while typing.get_origin(tp) is Annotated:
        args = typing.get_args(tp)
        tp = args[0]
        for m in args[1:]:
            meta.extend(m.metadata if isinstance(m, FieldInfo) else [m])
    return tp, meta


def _members(tp: Any) -> list:
    """The non-None members of a union (or ``[tp]``), Annotated stripped."""
    tp, _ = _strip(tp)
    if typing.get_origin(tp) in (Union, types.UnionType):
        return [m for a in typing.get_args(tp) for m in _members(a) if m is not type(None)]
    return [tp]


def _is_model(tp: Any) -> bool:
    return isinstance(tp, type) and issubclass(tp, BaseModel)


def _type_text(tp: Any) -> str:
    names = {int: "integer", float: "float", bool: "boolean", str: "string"}
    parts = []
    for m in _members(tp):
        origin, args = typing.get_origin(m), typing.get_args(m)
        if origin is Literal:
            parts.append(names.get(type(args[0]), "string"))
        elif origin is list:
            inner, meta = _strip(args[0])
            parts.append(f"array of {_type_text(inner)}" + (f" ({_range(meta)})" if _range(meta) else ""))
        elif origin is dict:
            parts.append(f"table of {_type_text(args[1])}")
        elif _is_model(m):
            parts.append("table")
        else:
            parts.append(names.get(m, getattr(m, "__name__", str(m))))
    return " or ".join(dict.fromkeys(parts))


def _num(x: Any) -> str:
    return f"{x:g}" if isinstance(x, float) else str(x)


def _range(meta: list) -> str:
    lo = hi = None
    out = []
    for m in meta:
        if isinstance(m, (at.Gt, at.Ge)):
            lo = ("(" if isinstance(m, at.Gt) else "[") + _num(getattr(m, "gt", getattr(m, "ge", None)))
        elif isinstance(m, (at.Lt, at.Le)):
            hi = _num(getattr(m, "lt", getattr(m, "le", None))) + (")" if isinstance(m, at.Lt) else "]")
        elif isinstance(m, (at.MinLen, at.MaxLen)):
            n_lo = next((x.min_length for x in meta if isinstance(x, at.MinLen)), None)
            n_hi = next((x.max_length for x in meta if isinstance(x, at.MaxLen)), None)
            text = (f"length {n_lo}" if n_lo == n_hi else f"length {n_lo}..{n_hi}" if n_lo is not None and n_hi
                    else f"length ≥ {n_lo}" if n_lo is not None else f"length ≤ {n_hi}")
            if text not in out:
                out.append(text)
        elif getattr(m, "pattern", None):
            out.append(f"matches {m.pattern}")
    if lo and hi:
        out.insert(0, f"{lo}, {hi}")
    elif lo:
        out.insert(0, ("> " if lo[0] == "(" else "≥ ") + lo[1:])
    elif hi:
        out.insert(0, ("< " if hi[-1] == ")" else "≤ ") + hi[:-1])
    return "; ".join(out)


def _allowed(f: FieldInfo) -> str:
    lits = [a for m in _members(f.annotation) if typing.get_origin(m) is Literal for a in typing.get_args(m)]
    if lits:
        return ", ".join(f"`{toml_value(a)}`" for a in lits)
    return _range(list(f.metadata))


def _default(f: FieldInfo) -> str:
    if f.default_factory is not None:
        v = f.default_factory()
    elif f.default is PydanticUndefined:
        return "required"
    else:
        v = f.default
    if v is None:
        return "—"
    if isinstance(v, BaseModel):
        return "(table)"
    if isinstance(v, list) and v and all(isinstance(x, BaseModel) for x in v):
        return f"{len(v)} tables"
    return f"`{toml_value(v)}`"


# ----------------------------------------------------------------------------------------- walking
def _rst(text: str) -> str:
    """reStructuredText roles and literals → Markdown code, whitespace collapsed."""
    text = re.sub(r":\w+:`~?([^`]+)`", r"`\1`", " ".join(text.split()))
    return text.replace("``", "`")


def _doc(cls: type) -> str:
    return _rst((cls.__doc__ or "").strip().split("\n\n")[0])


def split_unit(description: str) -> tuple[str, str]:
    """``"Image width [px]"`` → (``"Image width"``, ``"px"``)."""
    m = _UNIT.search(description or "")
    return ((description[:m.start()], m.group(1)) if m else (description or "", ""))


def _kinds(cls: type) -> list[str]:
    kind = cls.model_fields.get("kind")
    return [str(a) for m in _members(kind.annotation) for a in typing.get_args(m)] if kind else []


def iter_fields(model: type | None = None, prefix: str = ""):
    """Every (dotted key, model class, field name, FieldInfo) under ``model`` (default: the scenario model)."""
    if model is None:

        model = scenario_model()
    for name, f in model.model_fields.items():
        key = f"{prefix}{name}"
        yield key, model, name, f
        for sub in dict.fromkeys(m for m in _members(f.annotation) if _is_model(m)):
            yield from iter_fields(sub, f"{key}.")
        for m in _members(f.annotation):
            if typing.get_origin(m) is list and _is_model(_strip(typing.get_args(m)[0])[0]):
                yield from iter_fields(_strip(typing.get_args(m)[0])[0], f"{key}.<i>.")


def _walk(model: type, prefix: str, title: str, out: list[Section], note: str = "") -> None:
    """Append the section of ``model`` (keys under ``prefix``), then its tables depth-first; ``note`` tags the
    tables below a world or trajectory kind (``(world kind `ev5`)``)."""
    sec = Section(title, _doc(model))
    out.append(sec)
    children = []
    for name, f in model.model_fields.items():
        key = f"{prefix}{name}"
        desc, unit = split_unit(_rst(f.description or ""))
        sec.rows.append((f"`{key}`", _type_text(f.annotation), _default(f), _allowed(f), unit, desc))
        subs = list(dict.fromkeys(m for m in _members(f.annotation) if _is_model(m)))
        for sub in subs:
            kinds = " / ".join(f"`{k}`" for k in _kinds(sub)) if len(subs) > 1 else ""
            if kinds:  # one section per kind of a discriminated union; its tables say which kind they belong to
                children.append((sub, f"{key}.", f"`[{key}]` — kind {kinds}", f" ({key} kind {kinds})"))
            else:
                children.append((sub, f"{key}.", f"`[{key}]`{note}", note))
        for m in _members(f.annotation):
            inner = _strip(typing.get_args(m)[0])[0] if typing.get_origin(m) is list else None
            if _is_model(inner):
                children.append((inner, f"{key}.<i>.", f"`[[{key}]]`{note}", note))
    sec.rows.extend((f"`{prefix}{k}`", *rest) for k, *rest in LOADER_KEYS.get(prefix.rstrip("."), ()))
    if prefix == "sensor.":
        sec.rows.extend(_sensor_rows())
    for sub, pre, tit, below in children:
        _walk(sub, pre, tit, out, below)


def _sensor_rows() -> list[tuple[str, ...]]:
    """``[sensor]`` keys: the fields of :class:`renderlab.sensor.model.SensorOptions` (numpy-style docstring)."""
    doc = (SensorOptions.__doc__ or "").split("Attributes", 1)[-1]
    text = {m.group(1): " ".join(m.group(3).split()) for m in
            re.finditer(r"^\s{4}(\w+) : ([^\n]+)\n((?:\s{8}[^\n]*\n?)+)", doc, re.M)}
    rows = []
    for f in dataclasses.fields(SensorOptions):
        unit = next((u for s, u in _SENSOR_UNITS.items() if f.name.endswith(s)), "")
        default = "—" if f.default is None else f"`{toml_value(f.default)}`"
        kind = str(f.type).replace(" | None", "")
        rows.append((f"`sensor.{f.name}`", {"float": "float", "int": "integer"}.get(kind, kind), default, "",
                     unit, _rst(text.get(f.name, ""))))
    return rows


def sections() -> list[Section]:
    """The reference's sections, in file order (top level first, then each table depth-first)."""
    out: list[Section] = []
    _walk(scenario_model(), "", "Top level", out)
    return out


def render() -> str:
    """The whole reference as Markdown (deterministic: no paths, dates or versions)."""
    lines = ["# Scenario key reference", "",
             f"Generated from the pydantic models by `{REGENERATE}`; do not edit by hand "
             "(`tests/test_keyref.py` fails when it is stale).", "",
             "Every key can be given in the scenario file or on the command line as `--set KEY=VALUE` (a TOML "
             "value; list items by index, `--set world.bodies.0.albedo=0.4`). `renderlab show SCENARIO` prints a "
             "scenario's resolved keys. Unknown keys are refused. World kind → trajectory kinds: "
             + "; ".join(f"`{w}`: {', '.join(f'`{k}`' for k in ks)}" for w, ks in WORLD_TRAJECTORIES.items())
             + ".", ""]
    head = "| key | type | default | allowed | unit | description |"
    for sec in sections():
        lines += [f"## {sec.title}", ""] + ([sec.doc, ""] if sec.doc else [])
        lines += [head, "|---|---|---|---|---|---|"]
        lines += ["| " + " | ".join(c.replace("|", "\\|") or "" for c in row) + " |" for row in sec.rows]
        lines.append("")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """``python -m renderlab.scenario.keyref [--check | --stdout] [--out FILE]``."""
    import argparse

    p = argparse.ArgumentParser(prog="python -m renderlab.scenario.keyref", description=__doc__.split("\n")[0])
    p.add_argument("--check", action="store_true", help="exit 1 if the file differs from a fresh generation")
    p.add_argument("--stdout", action="store_true", help="print the reference instead of writing it")
    p.add_argument("--out", type=Path, default=DOC, help=f"file to write (default: {DOC.name} in docs/)")
    args = p.parse_args(argv)
    text = render()
    if args.stdout:
        sys.stdout.write(text)
        return 0
    if args.check:
        same = args.out.is_file() and args.out.read_text(encoding="utf-8") == text
        print(f"{args.out}: {'up to date' if same else f'stale; regenerate with {REGENERATE}'}")
        return 0 if same else 1
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text, encoding="utf-8")
    print(f"wrote {args.out} ({len(text.splitlines())} lines)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
