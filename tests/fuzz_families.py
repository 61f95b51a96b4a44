"""Generated must-refuse cases by category (the families of tests/test_fuzz_files.py), each
``(id, setup, argv, needle)``: ``setup`` prepares the case's private copy of the lab (:func:`fuzz_files.prepare`),
``argv`` runs with ``{LAB}`` and ``{CASE}`` filled in, ``needle`` is what the one error line must name.

* ``metadata`` — every key the models of ``campaign.json``, ``status.json``, ``runs.json`` and ``manifest.json``
  declare (:mod:`renderlab.contracts.file_models`), walked over real files: deleted where required, and given values
  of the wrong kind for its annotation (a number as a string, NaN, ±inf, a boolean, a list, a table, past its
  bounds, a 100 000-character string), plus an unknown key in every closed record and broken whole files;
* ``tables`` — the campaign and published tables: each core column dropped and retyped, known columns retyped, all
  rows removed, truncated / flipped / garbage files, and special files in their place;
* ``values`` — numbers the scenario schema let through: every numeric key of every shipped scene given as a
  string, intrinsics and distortion at 1e308, epochs outside the supported years, complex numbers, zero
  quaternions and NaN/huge values in a truth set's manifest, out-of-range command-line numbers;
* ``resources`` — inputs that could hang or exhaust the machine: FIFOs, links to devices, folders, link loops and
  oversized sparse files in every file slot; YAML alias bombs; image headers claiming huge sizes (PNG, TIFF, FITS)
  or another size than the camera's; deep JSON; worker counts past the cap;
* ``references`` — ``module:attr`` forms and objects that are not what the registry takes;
* ``outputs`` — writer inputs that would corrupt or overwrite what is written.
"""

from __future__ import annotations

import json
import math
import types
import typing

from fuzz_files import CASE, DELETE, LAB, _json_value

LONG = "x" * 200_000  # past every string bound of the models (the longest: 100 000)


# ------------------------------------------------------------------------------------------- model walking
def _types(tp) -> list:
    origin = typing.get_origin(tp)
    if origin is typing.Annotated:
        return _types(typing.get_args(tp)[0])
    if origin is typing.Union or origin is types.UnionType:
        return [t for a in typing.get_args(tp) for t in _types(a)]
    return [tp]


def _metas(f) -> list:
    out = list(getattr(f, "metadata", []))

    def walk(tp):
        if typing.get_origin(tp) is typing.Annotated:
            args = typing.get_args(tp)
            walk(args[0])
            for m in args[1:]:
                out.extend(getattr(m, "metadata", [m]))
        elif typing.get_origin(tp) in (typing.Union, types.UnionType):
            for a in typing.get_args(tp):
                walk(a)
    walk(f.annotation)
    return out


def _is_model(t) -> bool:
    from pydantic import BaseModel

    return isinstance(t, type) and issubclass(t, BaseModel)


def bad_values(field) -> list[tuple[str, object]]:
    """(tag, value) the field's annotation must refuse."""
    ts = _types(field.annotation)
    base = {typing.get_origin(t) or t for t in ts}
    metas = _metas(field)
    bounds = {k: getattr(m, k) for m in metas for k in ("gt", "ge", "lt", "le") if getattr(m, k, None) is not None}
    maxlen = next((m.max_length for m in metas if getattr(m, "max_length", None)), None)
    out: list = []
    if typing.Any in base:
        return out
    if type(None) not in base:
        out.append(("null", None))
    if int in base and float not in base:
        out += [("str_int", "64"), ("frac", 1.5), ("bool", True), ("list", [1])]
        if "le" in bounds or "lt" in bounds:
            out.append(("above", bounds["le"] + 1 if "le" in bounds else bounds["lt"]))
        if "ge" in bounds or "gt" in bounds:
            out.append(("below", (bounds.get("ge", bounds.get("gt")) or 0) - 1))
    elif float in base:
        out += [("str_num", "1.5"), ("nan", math.nan), ("inf", math.inf), ("bool", True), ("complex", "1+2j")]
        if "le" in bounds or "lt" in bounds:
            out.append(("e308", 1e308))
        if "ge" in bounds or "gt" in bounds:
            out.append(("ne308", -1e308))
    if str in base:
        out += [("int", 12345), ("bool_s", False)] + ([("long", LONG)] if maxlen else [])
    if typing.Literal in base:
        out.append(("choice", "no_such_choice"))
    if list in base:
        out += [("scalar_l", "abc"), ("table_l", {"a": 1})]
    if dict in base or any(_is_model(t) for t in ts):
        out += [("scalar_d", "abc"), ("list_d", [1, 2])]
    seen, uniq = set(), []
    for tag, v in out:
        if tag not in seen:
            seen.add(tag)
            uniq.append((tag, v))
    return uniq


def walk_model(model, data, path=()):
    """(path, field, value, model) of every declared field present in ``data`` (nested models and list items
    entered: the first item of a list of models), and (path, None, None, model) for each closed model reached."""
    if not isinstance(data, dict):
        return
    yield path, None, None, model
    for name, f in model.model_fields.items():
        if name not in data:
            continue
        p = (*path, name)
        yield p, f, data[name], model
        value = data[name]
        subs = [t for t in _types(f.annotation) if _is_model(t)]
        lists = [typing.get_args(t)[0] for t in _types(f.annotation) if typing.get_origin(t) is list]
        items = [t for lt in lists for t in _types(lt) if _is_model(t)]
        if subs and isinstance(value, dict):
            yield from walk_model(subs[0], value, p)
        elif items and isinstance(value, list) and value and isinstance(value[0], dict):
            yield from walk_model(items[0], value[0], (*p, 0))


def loc_text(path) -> str:
    """A key path as the error line names it (``plan.seed.entropy``, ``frames[0].time_s``, ``[0].status``)."""
    out = ""
    for part in path:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out + ":"


def metadata_mutations(model, data) -> list[tuple[str, list, object, str]]:
    """(tag, path, value, needle) of every must-refuse change of ``data`` under ``model``."""
    out = []
    for path, f, _value, m in walk_model(model, data):
        if f is None:
            if m.model_config.get("extra") == "forbid":
                out.append(("bogus_key", [*path, "bogus_key"], 1, "bogus_key"))
            continue
        needle = loc_text(path)
        if f.is_required():
            out.append(("deleted", list(path), DELETE, needle))
        out += [(tag, list(path), v, needle) for tag, v in bad_values(f)]
    return out


# ------------------------------------------------------------------------------------------- metadata
def _metadata_files(lab) -> list:
    """(tag, folder, file in it, model, data, commands)."""
    from renderlab.contracts.file_models import CampaignManifest, RunStatus, TruthManifest

    camp_cmds = [["report", f"{CASE}/camp", "--out", "out"], ["info", f"{CASE}/camp"],
                 ["publish", f"{CASE}/camp", "--out", "out"]]
    pub_cmds = [["report", f"{CASE}/pub"], ["info", f"{CASE}/pub"]]
    ts_cmds = [["export", f"{CASE}/ts", "--oem", "x.oem", "--epoch-utc", "2024-01-01T00:00:00"], ["info", f"{CASE}/ts"],
               ["measure", f"{CASE}/ts", "--method", "retina"]]
    read = lambda p: json.loads((lab / p).read_text())  # noqa: E731
    return [("campaign", "camp", "campaign.json", CampaignManifest, read("camp/campaign.json"), camp_cmds),
            ("published", "pub", "campaign.json", CampaignManifest, read("pub/campaign.json"), pub_cmds),
            ("status", "camp", "runs/000000/status.json", RunStatus, read("camp/runs/000000/status.json"), camp_cmds),
            ("manifest", "ts", "manifest.json", TruthManifest, read("ts/manifest.json"), ts_cmds)]


def _runs_json_cases(lab) -> list:
    from renderlab.contracts.file_models import RunStatus

    doc = json.loads((lab / "pub/runs.json").read_text())  # {format, plan_digest, runs}; a bare list is read too
    data = doc["runs"]
    cmds = [["report", f"{CASE}/pub"], ["info", f"{CASE}/pub"]]
    out = []
    for k, (tag, path, value, _) in enumerate(metadata_mutations(RunStatus, data[0])):
        needle = loc_text(("runs", 0, *path)) if tag != "bogus_key" else "bogus_key"
        out.append((f"runs.json:{'.'.join(map(str, path))}={tag}", [["copy", "pub"], ["json", "pub/runs.json",
                   ["runs", 0, *path], _json_value(value)]], cmds[k % 2], needle))
    for tag, text, needle in [("not_a_list", "{}", "runs.json"), ("twice", json.dumps(data + data[:1]), "twice"),
                              ("beyond_plan", json.dumps(data + [{**data[0], "run": 7}]), "run 7"),
                              ("other_campaign", json.dumps({**doc, "plan_digest": "0" * 16}), "another campaign")]:
        out.append((f"runs.json:{tag}", [["copy", "pub"], ["json_text", "pub/runs.json", text]], cmds[0], needle))
    return out


BROKEN = [("empty", "", ""), ("not_json", "{not json", "not valid JSON"), ("top_list", "[1, 2]", ""),
          ("deep", "[" * 100_000 + "]" * 100_000, "deeply"), ("nan_text", "NaN", ""), ("bom_utf16", None, ""),
          ("long_string", json.dumps(LONG), "")]


def metadata_cases(lab) -> list:
    out = []
    for tag, folder, name, model, data, cmds in _metadata_files(lab):
        for k, (mtag, path, value, needle) in enumerate(metadata_mutations(model, data)):
            out.append((f"{tag}:{'.'.join(map(str, path))}={mtag}",
                        [["copy", folder], ["json", f"{folder}/{name}", path, _json_value(value)]],
                        cmds[k % len(cmds)], needle))
        for k, (btag, text, needle) in enumerate(BROKEN):
            step = (["bytes_hex", f"{folder}/{name}", '{"format": 1}'.encode("utf-16").hex()] if text is None
                    else ["json_text", f"{folder}/{name}", text])
            out.append((f"{tag}:whole={btag}", [["copy", folder], step], cmds[k % len(cmds)], needle))
    return out + _runs_json_cases(lab)


# ------------------------------------------------------------------------------------------- tables
SPECIAL_WORDS = {"fifo": "FIFO", "zero": "character device", "urandom": "character device", "null": "character device",
                 "folder": "folder", "dangling": "not found", "loop": "symbolic links"}


def tables_cases(lab) -> list:
    import pyarrow as pa
    import pyarrow.parquet as pq

    from renderlab.contracts.schemas import LANDMARK_CORE, LANDMARK_RUNNER

    out = []
    t = pq.read_table(lab / "camp/runs/000000/measurements.parquet")
    extra = [f.name for f in LANDMARK_RUNNER if f.name in t.column_names and f.name not in LANDMARK_CORE.names]
    slots = [("camp", ["camp/runs/000000/measurements.parquet", "camp/runs/000001/measurements.parquet"],
              [["report", f"{CASE}/camp", "--out", "out"], ["publish", f"{CASE}/camp", "--out", "out"]]),
             ("pub", ["pub/tables/measurements.parquet"], [["report", f"{CASE}/pub"], ["report", f"{CASE}/pub", "--out",
                                                                                        "out"]])]
    for folder, files, cmds in slots:
        f0 = files[0]
        size = (lab / f0).stat().st_size
        ops = ([("drop", c, c) for c in LANDMARK_CORE.names] + [("retype", c, c) for c in LANDMARK_CORE.names + extra]
               + [("truncate", n, "Parquet") for n in (0, 4, 8, 64, size // 2, size - 1, size - 4, size - 8)]
               + [("flip", n, "Parquet") for n in range(1, 9)]
               + [("garbage", "PAR1 not really a table PAR1", "Parquet")])
        for k, (op, arg, needle) in enumerate(ops):
            out.append((f"table:{folder}:{op}={arg}", [["copy", folder], ["table", f0, op, arg]], cmds[k % 2], needle))
        out.append((f"table:{folder}:no_rows", [["copy", folder], *[["table", f, "empty", None] for f in files]],
                    cmds[0], "no rows"))
        for k, (kind, word) in enumerate(SPECIAL_WORDS.items()):
            if folder == "pub" and kind in ("zero", "urandom", "null", "dangling", "loop"):
                word = "no links"  # a published folder's tables are never links
            out.append((f"table:{folder}:special={kind}", [["copy", folder], ["special", f0, kind]], cmds[k % 2], word))
    p = "camp/runs/000000/perturbations.parquet"
    pt = pq.read_table(lab / p)
    num = next(c for c in pt.column_names if c not in ("campaign", "run") and pa.types.is_floating(pt.schema.field(c).type))
    out += [("table:other:truncated", [["copy", "camp"], ["table", p, "truncate", 10]],
             ["report", f"{CASE}/camp", "--out", "out"], "Parquet"),
            ("table:other:do_not_fit", [["copy", "camp"], ["table", p, "retype", num]],
             ["report", f"{CASE}/camp", "--out", "out"], "fit together"),
            ("table:status_names_missing_table",
             [["copy", "camp"], ["json", "camp/runs/000000/status.json", ["tables", 0], "ghost_table"]],
             ["report", f"{CASE}/camp", "--out", "out"], "ghost_table"),
            ("table:published_name_not_identifier", [["copy", "pub"], ["text", "pub/tables/bad-name.parquet", "x"]],
             ["report", f"{CASE}/pub"], "identifiers")]
    return out


# ------------------------------------------------------------------------------------------- outputs
def outputs_cases(lab) -> list:
    export = ["export", f"{LAB}/ts", "--epoch-utc", "2024-01-01T00:00:00"]
    out = []
    names = [chr(c) for c in [*range(0, 32), 127]] + [f"A{chr(c)}B" for c in (10, 13, 0, 27)] + \
            ["é", "Ω", "", "   ", "a" * 81, LONG, "CAMERA\nMETA_STOP"]
    for k, name in enumerate(names):
        out.append((f"outputs:object_name={k}", [], [*export, "--oem", f"{CASE}/x.oem", "--object-name", name],
                    "--object-name"))
    same = [("plain", "a.oem", "a.oem"), ("dot", "a.oem", "./a.oem"), ("abs", "a.oem", f"{CASE}/a.oem"),
            ("updown", "sub/../a.oem", "a.oem")]
    for tag, a, b in same:
        out.append((f"outputs:same_file={tag}", [["special", "sub", "folder"]],
                    [*export, "--oem", f"{CASE}/{a}", "--aem", b if b.startswith(CASE) else f"{CASE}/{b}"],
                    "same file"))
    for kind in ("folder", "fifo", "null", "zero", "dangling"):
        for flag in ("--oem", "--aem"):
            out.append((f"outputs:{flag[2:]}_is_{kind}", [["special", "o.kvn", kind]],
                        [*export, flag, f"{CASE}/o.kvn"], "not a regular file"))
    for k, epoch in enumerate(["0001-01-01T00:00:00", "1959-12-31T23:59:59", "2101-01-01T00:00:00",
                               "9999-12-31T00:00:00", "+10000-01-01T00:00:00", "x" * 1000, "2024-13-45T00:00:00"]):
        out.append((f"outputs:epoch={k}", [], ["export", f"{LAB}/ts", "--oem", f"{CASE}/e.oem", "--epoch-utc", epoch],
                    "epoch"))
    out += [("outputs:no_parent", [], [*export, "--oem", f"{CASE}/no/such/x.oem"], "does not exist"),
            ("outputs:exists", [["text", "x.oem", "keep me\n"]], [*export, "--oem", f"{CASE}/x.oem"], "exists"),
            ("outputs:publish_onto_file", [["text", "f", "a file\n"]],
             ["publish", f"{LAB}/camp", "--out", f"{CASE}/f"], "not a directory"),
            ("outputs:report_onto_file", [["text", "f", "a file\n"]],
             ["report", f"{LAB}/camp", "--out", f"{CASE}/f"], "not a directory")]
    return out


# ------------------------------------------------------------------------------------------- references
REF_FORMS = ["", ":", "x:", ":y", "a:b:c", "..x:y", ".x:y", "...a.b:c", "1x:y", "x-y:z", "x:y-z", "x y:z", "x:y z",
             "os.:system", "os:.system", "é:x", "os:system\n", "x" * 400 + ":y", "os/path:join", "os:system()"]
REF_OBJECTS = ["os:system", "os:getcwd", "os:remove", "shutil:rmtree", "subprocess:call", "subprocess:Popen",
               "builtins:exec", "builtins:eval", "builtins:print", "json:loads", "math:pi", "sys:argv", "os:environ",
               "os:path", "collections:OrderedDict", "pathlib:Path", "renderlab.contracts.landmark:LandmarkMethod",
               "renderlab.contracts.landmark:LandmarkMethodOptions", "renderlab.plugins:landmark_methods",
               "no_such_module_xyz:Thing", "os:no_such_attr", "renderlab.nope:x", "renderlab:nothing"]


def references_cases(lab) -> list:
    out = []
    for k, ref in enumerate(REF_FORMS + REF_OBJECTS):
        if ":" not in ref:
            continue  # a plain name is a registry name (an unknown one: tests/test_fuzz_inputs.py)
        out.append((f"ref:method={k}", [], ["measure", f"{LAB}/ts", "--method", ref], "--method"))
        camp = ["campaign", f"{LAB}/scene.toml", "--runs", "1", "--out", f"{CASE}/c", "--workers", "0", "--quiet"]
        out.append((f"ref:plugin={k}", [], [*camp, "--plugin", ref], "--plugin"))
        out.append((f"ref:named_plugin={k}", [], [*camp, "--plugin", f"mine={ref}"], "--plugin"))
    for k, text in enumerate(["bad name=os:getcwd", "=os:getcwd", "1x=os:getcwd", "a.b=os:getcwd"]):
        out.append((f"ref:plugin_name={k}", [], ["campaign", f"{LAB}/scene.toml", "--runs", "1", "--out", f"{CASE}/c",
                                                   "--workers", "0", "--plugin", text], "--plugin"))
    return out
