"""Generated bad inputs for tests/test_fuzz_inputs.py (see its docstring): :func:`cases` and the input files
they read (:func:`build_inputs`)."""

from __future__ import annotations

import json
import math
import os
import tomllib
import types
import typing
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PREFIX = "renderlab: error: "
CASE_SECONDS = 20.0
SCENES = sorted((REPO / "scenes").glob("*.toml"))
SCENARIO_COMMANDS = ("render", "crosscheck", "campaign")


# ------------------------------------------------------------------------------------------- generation
def _cmd(i: int, scene: str) -> list[str]:
    """The ``i``-th scenario command on ``scene`` (rotating render, crosscheck, campaign)."""
    c = SCENARIO_COMMANDS[i % 3]
    tail = ["--runs", "2", "--workers", "0"] if c == "campaign" else []
    return [c, scene, "--out", "out", "--quiet", *tail]


def _leaves(d, path=()):
    """(path, value) of every leaf: scalars and lists of scalars (lists of tables are entered)."""
    for k, v in d.items():
        p = (*path, k)
        if isinstance(v, dict):
            yield from _leaves(v, p)
        elif isinstance(v, list) and v and all(isinstance(x, dict) for x in v):
            for i, x in enumerate(v):
                yield from _leaves(x, (*p, str(i)))
        else:
            yield p, v


def _types(tp) -> list:
    """The alternatives of an annotation, Annotated and Optional unwrapped."""
    origin = typing.get_origin(tp)
    if origin is typing.Annotated:
        return _types(typing.get_args(tp)[0])
    if origin is typing.Union or origin is types.UnionType:
        return [t for a in typing.get_args(tp) for t in _types(a)]
    return [tp]


def _is_model(t) -> bool:
    from pydantic import BaseModel

    return isinstance(t, type) and issubclass(t, BaseModel)


def _field(candidates, node, path):
    """The pydantic FieldInfo of ``path`` inside ``node`` (validated by one of ``candidates``), or None."""
    models = [m for m in candidates if _is_model(m)]
    if isinstance(node, dict):
        fits = [m for m in models if set(node) <= set(m.model_fields) or m.model_config.get("extra") == "allow"]
        kind = node.get("kind")
        models = [m for m in fits if kind is None or "kind" not in m.model_fields
                  or kind in typing.get_args(m.model_fields["kind"].annotation)] or fits
    for m in models:
        f = m.model_fields.get(path[0])
        if f is None:
            continue
        if len(path) == 1:
            return f
        child = node[path[0]]
        if isinstance(child, list):
            inner = [t for c in _types(f.annotation) if typing.get_origin(c) is list
                     for t in _types(typing.get_args(c)[0])]
            return _field(inner, child[int(path[1])], path[2:]) if len(path) > 2 else None
        return _field(_types(f.annotation), child, path[1:])
    return None


def _bounds(f) -> dict:
    """gt/ge/lt/le declared on a field (its metadata and the Annotated types inside its annotation)."""
    metas = list(f.metadata)

    def walk(tp):
        origin = typing.get_origin(tp)
        if origin is typing.Annotated:
            args = typing.get_args(tp)
            walk(args[0])
            for m in args[1:]:
                metas.extend(getattr(m, "metadata", [m]))
        elif origin is typing.Union or origin is types.UnionType:
            for a in typing.get_args(tp):
                walk(a)
    walk(f.annotation)
    return {k: getattr(m, k) for m in metas for k in ("gt", "ge", "lt", "le") if getattr(m, k, None) is not None}


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf") if math.isinf(v) else repr(v)
    if isinstance(v, int):
        return str(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{json.dumps(k)} = {_toml_value(x)}" for k, x in v.items()) + "}"
    return v.isoformat()  # a TOML date-time


def to_toml(d: dict) -> str:
    """A scenario dict as TOML (each top-level key one line; inline tables)."""
    return "".join(f"{json.dumps(k)} = {_toml_value(v)}\n" for k, v in d.items())


def _bad_values(path, value, field, i: int) -> list[tuple[str, str]]:
    """(tag, TOML text) of values ``path`` must refuse (NaN, inf, wrong type, bool, past its bounds)."""
    from renderlab.contracts.config_types import accepts_bool

    is_bool_field = field is not None and accepts_bool(field.annotation)
    out = []
    if isinstance(value, bool):
        return [("int2", "2"), ("word", '"maybe"'), ("float", "1.5"), ("list", "[true]")][i % 2::2]
    if isinstance(value, (int, float)):
        out += [("nan", "nan"), (("inf", "inf"), ("ninf", "-inf"))[i % 2], (("text", '"abc"'), ("table", "{x = 1}"))[i % 2]]
        if not is_bool_field:
            out.append(("bool", "true"))
        is_int = isinstance(value, int) and field is not None and int in _types(field.annotation)
        if is_int:
            out.append(("frac", "1.5"))
        for k, b in (_bounds(field) if field is not None else {}).items():
            step = 1 if is_int else max(1.0, abs(b))
            if k == "gt":
                out += [("at_gt", repr(b)), ("neg", repr(b - step))]
            elif k == "ge":
                out.append(("below_ge", repr(b - step)))
            elif k == "lt":
                out.append(("at_lt", repr(b)))
            else:
                out += [("above_le", repr(b + step)), ("huge", "1000000000000000000" if is_int else "1e300")]
    elif isinstance(value, str):
        out.append((("int", "12345"), ("list", '["a"]'))[i % 2])
        out += [] if is_bool_field else [("bool", "true")]
        if field is not None and all(typing.get_origin(t) is typing.Literal for t in _types(field.annotation)
                                     if t is not type(None)):
            out.append(("choice", '"no_such_choice"'))
    elif isinstance(value, list) and value and all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                                   for x in value):
        n = len(value)
        out += [("nan_item", _toml_value([math.nan] * n)), ("bool_items", _toml_value([True] * n)),
                (("text_items", _toml_value(["a"] * n)), ("scalar", "3.5"))[i % 2]]
    elif isinstance(value, list) and value and all(isinstance(x, list) for x in value):
        out += [("flat", _toml_value([math.nan] * len(value))), ("scalar", "3.5")]
    return out


def _needle(path) -> str:
    """What the error line must name: the key's last plain component."""
    return next(p for p in reversed(path) if not p.isdigit())


def _scenario_cases(files: dict) -> list:
    from renderlab.scenario import scenario_model

    model = scenario_model()
    out, k = [], 0
    for scene in SCENES:
        data = tomllib.loads(scene.read_text(encoding="utf-8"))
        ref = f"{{IN}}/{scene.name}"
        files[scene.name] = scene.read_text(encoding="utf-8")
        tables = set()
        for i, (path, value) in enumerate(_leaves(data)):
            key = ".".join(path)
            field = _field([model], data, list(path))
            for tag, text in _bad_values(path, value, field, i):
                out.append((f"{scene.stem}:{key}={tag}", [*_cmd(k, ref), "--set", f"{key}={text}"], _needle(path)))
                k += 1
            if field is not None and field.is_required():
                name = f"del_{scene.stem}_{key}.toml"
                pruned = json.loads(json.dumps(data, default=str))
                node = pruned
                for p in path[:-1]:
                    node = node[int(p)] if isinstance(node, list) else node[p]
                del node[path[-1]]
                files[name] = to_toml(pruned)
                out.append((f"{scene.stem}:{key}=deleted", _cmd(k, f"{{IN}}/{name}"), path[-1]))
                k += 1
            for j in range(len(path) - 1):
                parent = path[:j + 1]
                f = _field([model], data, list(parent)) if not parent[-1].isdigit() else None
                cands = [t for t in _types(f.annotation) if _is_model(t)] if f is not None else []
                if cands and all(c.model_config.get("extra") == "forbid" for c in cands) and parent not in tables:
                    tables.add(parent)
                    where = ".".join(parent)
                    out.append((f"{scene.stem}:{where}.bogus_key", [*_cmd(k, ref), "--set", f"{where}.bogus_key=1"],
                                "bogus_key"))
                    k += 1
        out.append((f"{scene.stem}:bogus_top", [*_cmd(k, ref), "--set", "bogus_top=1"], "bogus_top"))
    return out


def _cost_cases() -> list:
    """Keys valid one by one, a request too large together (renderlab.commands.cost)."""
    a, e, u = "{IN}/analytic_sphere_box.toml", "{IN}/ev5_descent.toml", "{IN}/unknown_satellite.toml"
    big = ["--set", "camera.width=16384", "--set", "camera.height=16384"]
    return [
        ("cost:spp_65536", ["render", a, "--out", "out", "--set", "render.spp=65536"], "too large"),
        ("cost:spp_65536_crosscheck", ["crosscheck", a, "--out", "out", "--set", "render.spp=65536"], "too large"),
        ("cost:ev5_facet_0.3", ["render", e, "--out", "out", "--set", "world.facet_m=0.3"], "facets"),
        ("cost:ev5_cell_0.001", ["render", e, "--out", "out", "--set", "world.site.cell_m=0.001"], "site cells"),
        ("cost:ev5_cell_campaign", ["campaign", e, "--runs", "2", "--out", "out", "--workers", "0",
                                    "--set", "world.site.cell_m=0.001"], "site cells"),
        ("cost:camera_16k", ["render", a, "--out", "out", *big], "too large"),
        ("cost:frames_100k", ["render", u, "--out", "out", "--set", "trajectory.frames=100000"], "too large"),
        ("cost:runs_1e6", ["campaign", u, "--runs", "1000000", "--out", "out", "--workers", "0"], "too large"),
        ("cost:ev5_no_frames", ["render", e, "--out", "out", "--set", "trajectory.altitudes_m=[]"], "no frames"),
        ("cost:ev5_no_frames_campaign", ["campaign", e, "--runs", "2", "--out", "out", "--workers", "0",
                                         "--set", "trajectory.altitudes_m=[]"], "no frames"),
    ]


DEEP = 100_000
BAD_TOML = {
    "unclosed_table.toml": "[camera\nwidth = 3\n",
    "duplicate_key.toml": "name = 'a'\nname = 'b'\n",
    "duplicate_table.toml": "[sun]\n[sun]\n",
    "bare_value.toml": "just some words\n",
    "unterminated_string.toml": 'name = "abc\n',
    "bad_escape.toml": 'name = "\\q"\n',
    "trailing_comma.toml": "a = [1, 2,,]\n",
    "equals_only.toml": "=\n",
    "tab_in_key.toml": "na\tme = 1\n",
    "empty.toml": "",
    "comments_only.toml": "# nothing here\n# at all\n",
    "world_is_number.toml": "world = 3\n",
    "world_is_string.toml": 'world = "analytic"\n',
    "world_array_of_tables.toml": '[[world]]\nkind = "analytic"\n',
    "world_no_bodies.toml": '[world]\nkind = "analytic"\n',
    "world_empty_bodies.toml": '[world]\nkind = "analytic"\nbodies = []\n',
    "top_level_array.toml": "[[bodies]]\nname = 'x'\n",
    "huge_integer.toml": "[camera]\nwidth = " + "9" * 5000 + "\n",
    "deep_arrays.toml": "a = " + "[" * DEEP + "]" * DEEP + "\n",
    "deep_inline_tables.toml": "a = " + "{b = " * DEEP + "1" + "}" * DEEP + "\n",
    "deep_dotted_key.toml": ".".join(["a"] * DEEP) + " = 1\n",
    "deep_table_header.toml": "[" + ".".join(["a"] * DEEP) + "]\n",
    "deep_unclosed.toml": "a = " + "[" * DEEP + "\n",
}
BAD_BYTES = {
    "binary.toml": bytes(range(256)) * 8,
    "nul_bytes.toml": b"name = \"a\x00b\"\n",
    "utf16_bom.toml": 'name = "x"\n[world]\nkind = "analytic"\n'.encode("utf-16"),
    "utf16_le.toml": 'name = "x"\n'.encode("utf-16-le"),
    "latin1.toml": 'name = "caf\xe9"\n'.encode("latin-1"),
    "utf8_bom.toml": b"\xef\xbb\xbfname = 'x'\n",
}


def build_inputs(d: Path) -> None:
    """Write every input file the cases name into ``d`` (scenario copies, bad TOML, special files)."""
    d.mkdir(parents=True, exist_ok=True)
    files: dict = {}
    _scenario_cases(files)
    for name, text in {**files, **BAD_TOML}.items():
        (d / name).write_text(text, encoding="utf-8")
    for name, data in BAD_BYTES.items():
        (d / name).write_bytes(data)
    with open(d / "oversized.toml", "wb") as fh:  # sparse: 17 MiB of NULs
        fh.truncate(17 * 1024 * 1024)
    (d / "a_folder.toml").mkdir()
    os.mkfifo(d / "fifo.toml")
    os.symlink("loop_b.toml", d / "loop.toml")
    os.symlink("loop.toml", d / "loop_b.toml")
    os.symlink("nowhere.toml", d / "dangling.toml")
    (d / "a_file").write_text("a regular file\n")
    (d / "empty_dir").mkdir()
    (d / "bad_campaign").mkdir()
    (d / "bad_campaign" / "campaign.json").write_text("{not json")
    (d / "huge_campaign").mkdir()
    (d / "huge_campaign" / "campaign.json").write_text(json.dumps(
        {"format": "renderlab.campaign/1", "plan": {"runs": 10 ** 12, "study": "analytic_pointing"}}))


def _file_cases() -> list:
    names = [*BAD_TOML, *BAD_BYTES, "oversized.toml", "a_folder.toml", "fifo.toml", "loop.toml", "dangling.toml"]
    out = [(f"file:{n}", _cmd(i, f"{{IN}}/{n}"), "") for i, n in enumerate(names)]
    for i, dev in enumerate(["/dev/null", "/dev/zero", "/proc/self/status", "/proc/self/mem", "/"]):
        out.append((f"file:{dev}", _cmd(i, dev), ""))
    return out


A = "{IN}/analytic_sphere_box.toml"
LONG = "a" * 300
SET_FORMS = [
    "camera.width", "=3", "camera..width=3", ".camera=3", "camera.=3", "camera.width=", "camera.width=[",
    "camera.width={", 'camera.width="unterminated', "trajectory.altitudes_m=[]", "world.bodies.².albedo=0.1",
    f"world.{LONG}=1", f"world.bodies.0.{LONG}=1", "world.bodies.99.albedo=0.1", "world.bodies.-1.albedo=0.1",
    "world.bodies.x.albedo=0.1", "camera.width.x=1", "camera=3", "world=[]", "world.bodies=[]",
    "render.spp=1e400", "camera.width=" + "9" * 5000, "camera.width=" + "[" * DEEP,
    ".".join("abcdefghijklmnopqrstuvwxyzABCDEFGH") + "=1", "camera.wid th=3", "camera.width\x00=3",
    "caméra.width=3", "sun.direction=[0,0,0]", "world.kind=mars", "sensor.bits=1e9",
]


def _set_cases() -> list:
    assert len(SET_FORMS) == 30
    return [(f"set:{i:02d}", [*_cmd(i, A), "--set", s], "") for i, s in enumerate(SET_FORMS)]


def _flag_cases() -> list:
    r, v = ["render", A, "--out", "out"], ["visibility", "--out", "out"]
    c = ["campaign", A, "--runs", "2", "--out", "out"]
    m = ["measure", "{IN}/empty_dir", "--method", "retina"]
    flags = {
        "render": [r + ["--frames", "0"], r + ["--frames", "-1"], r + ["--frames", "abc"], r + ["--frames", "1.5"],
                   r + ["--seed", "-1"], r + ["--seed", "x"], r + ["--renderer", "povray"], r + ["--bogus"],
                   ["render", A], ["render"], ["render", A, "--out", ""], ["render", A, "--out", "   "],
                   ["render", A, "--out", f"x/{LONG}"], ["render", A, "--out", "o\x00x"],
                   ["render", A, "--out", ".", "--overwrite"], ["render", A, "--out", "{IN}", "--overwrite"],
                   ["render", A, "--out", "{IN}/a_file"], ["render", A, "--out", "{IN}/a_file/sub"],
                   ["render", "{IN}/no_such.toml", "--out", "out"], ["render", "", "--out", "out"],
                   ["render", f"{LONG}.toml", "--out", "out"]],
        "campaign": [c[:3] + ["0", "--out", "out"], c[:3] + ["-1", "--out", "out"], c[:3] + ["abc", "--out", "out"],
                     c[:3] + ["2000000", "--out", "out", "--workers", "0"], c + ["--workers", "-1"],
                     c + ["--workers", "abc"], c + ["--workers", "1000"], c + ["--connect-timeout", "0"],
                     c + ["--connect-timeout", "-1"], c + ["--connect-timeout", "nan"], c + ["--connect-timeout", "inf"],
                     c + ["--connect-timeout", "abc"], c + ["--scheduler", "http://x:1"], c + ["--scheduler", "tcp://h"],
                     c + ["--scheduler", "tcp://h:0"], c + ["--scheduler", "tcp://h:99999"], c + ["--scheduler", ""],
                     c + ["--scheduler", "tcp://127.0.0.1:9", "--workers", "2"], c + ["--tls-ca-file", "{IN}/a_file"],
                     c + ["--scheduler", "tcp://127.0.0.1:9", "--tls-ca-file", "{IN}/a_file"],
                     c + ["--scheduler", "tls://127.0.0.1:9"],
                     c + ["--scheduler", "tls://127.0.0.1:9", "--tls-ca-file", "{IN}/a_file", "--tls-cert", "x"],
                     c + ["--scheduler", "tls://127.0.0.1:9", "--tls-ca-file", "{IN}/nope.pem"],
                     c + ["--scheduler", "tls://127.0.0.1:9", "--tls-ca-file", "{IN}/a_file"],
                     c + ["--seed", "-1"], c + ["--plugin", "no_such_module_xyz:Thing"],
                     c + ["--plugin", "bad name=os:getcwd"], c + ["--timings", "sometimes"], c + ["--bogus"],
                     ["campaign", A, "--out", "out"], ["campaign", A, "--runs", "2"], ["campaign"],
                     ["campaign", A, "--runs", "2", "--out", ""]],
        "crosscheck": [["crosscheck", A, "--out", "out", "--frames", "0"], ["crosscheck", A, "--bogus"],
                       ["crosscheck", A], ["crosscheck", A, "--out", ""], ["crosscheck", "{IN}/a_folder.toml",
                                                                             "--out", "out"]],
        "visibility": [v + ["--hours", "nan"], v + ["--hours", "inf"], v + ["--hours", "0"], v + ["--hours", "-1"],
                       v + ["--hours", "1e9"], v + ["--hours", "abc"], v + ["--cadence-s", "0"],
                       v + ["--cadence-s", "nan"], v + ["--cadence-s", "-5"], v + ["--cadence-s", "1e-9"],
                       v + ["--altitude-km", "10"], v + ["--altitude-km", "nan"], v + ["--altitude-km", "1e9"],
                       v + ["--inclinations", "a,b"], v + ["--inclinations", ","], v + ["--inclinations", "200"],
                       v + ["--inclinations", "nan"], v + ["--fovs", "0"], v + ["--fovs", "120"], v + ["--fovs", "nan"],
                       v + ["--fovs", ""], v + ["--cloud-cover", "1"], v + ["--cloud-cover", "-0.1"],
                       v + ["--cloud-cover", "nan"], v + ["--seed", "-1"], v + ["--seed", "abc"],
                       v + ["--epoch", "yesterday"], v + ["--bogus"], ["visibility"], ["visibility", "--out", ""],
                       ["visibility", "--out", "{IN}/a_file"], v + ["--inclinations", ",".join(["10"] * 100000)]],
        "measure": [["measure", "{IN}/no_such_set", "--method", "retina"], ["measure", "{IN}/a_file", "--method",
                                                                           "retina"],
                    m, ["measure", "{IN}/empty_dir", "--method", "no_such_method"], m + ["--seed", "-1"],
                    m + ["--sigma-pos-m", "nan"], m + ["--sigma-pos-m", "-1"], m + ["--n-sigma", "inf"],
                    m + ["--max-search-px", "abc"], m + ["--peak", "bogus"], m + ["--photometry", "bogus"],
                    m + ["--bogus"], ["measure", "{IN}/empty_dir"], ["measure"], m + ["--out", ""]],
        "report": [["report", "{IN}/no_such_campaign", "--out", "out"], ["report", "{IN}/a_file", "--out", "out"],
                   ["report", "{IN}/empty_dir", "--out", "out"], ["report", "{IN}/bad_campaign", "--out", "out"],
                   ["report", "{IN}/huge_campaign", "--out", "out"], ["report", "{IN}/bad_campaign"],
                   ["report", "{IN}/empty_dir", "--bogus"], ["report"], ["report", "{IN}/empty_dir", "--out", ""]],
        "publish": [["publish", "{IN}/empty_dir"], ["publish", "{IN}/no_such_campaign", "--out", "out"],
                    ["publish", "{IN}/a_file", "--out", "out"], ["publish", "{IN}/bad_campaign", "--out", "out"],
                    ["publish", "{IN}/huge_campaign", "--out", "out"], ["publish"]],
        "demo": [["demo", "--bogus"], ["demo", "--out", ""], ["demo", "--out", f"x/{LONG}"],
                 ["demo", "--out", "{IN}/a_file"]],
        "top": [[], ["paint"], ["--bogus"], ["render", "--bogus"]],
    }
    return [(f"flag:{cmd}:{i:02d}", argv, "") for cmd, lst in flags.items() for i, argv in enumerate(lst)]


def cases() -> list:
    """Every case: (id, argv with ``{IN}`` for the inputs folder, a substring the error must contain or '')."""
    return [*_scenario_cases({}), *_cost_cases(), *_file_cases(), *_set_cases(), *_flag_cases()]


CASES = cases()
