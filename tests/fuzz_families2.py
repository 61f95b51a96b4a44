"""The ``values`` and ``resources`` families of tests/test_fuzz_files.py (see tests/fuzz_families.py)."""

from __future__ import annotations

import json
import math
import tomllib

from fuzz_files import (
    CASE,
    LAB,
    REPO,
    H,
    W,
    _json_value,
    alias_bomb,
    apriori_data,
    fits_header,
    png_header,
    tiff_header,
    tiny_scene_text,
)

SCENES = sorted((REPO / "scenes").glob("*.toml"))
RENDER_CMDS = ("render", "campaign", "crosscheck")


def _cmd(k: int, scene: str, *extra) -> list[str]:
    c = RENDER_CMDS[k % 3]
    tail = ["--runs", "2", "--workers", "0"] if c == "campaign" else []
    return [c, scene, "--out", f"{CASE}/out", "--quiet", *tail, *extra]


def _numbers_only(field) -> bool:
    from fuzz_cases import _types

    arms = [t for t in _types(field.annotation) if t is not type(None)]
    return bool(arms) and all(t in (int, float) for t in arms)


def _list_of_numbers(field) -> bool:
    import typing

    from fuzz_cases import _types

    for t in _types(field.annotation):
        if typing.get_origin(t) is list:
            inner = [a for a in _types(typing.get_args(t)[0]) if a is not type(None)]
            if inner and all(a in (int, float) for a in inner):
                return True
    return False


def _string_number_cases() -> list:
    """Every numeric key of every shipped scene given as a string (``width = "64"``): refused, not coerced."""
    from fuzz_cases import _field, _leaves

    from renderlab.scenario import scenario_model

    model, out, k = scenario_model(), [], 0
    for scene in SCENES:
        data = tomllib.loads(scene.read_text(encoding="utf-8"))
        for path, value in _leaves(data):
            field = _field([model], data, list(path))
            if field is None:
                continue
            key = ".".join(path)
            needle = next(p for p in reversed(path) if not p.isdigit())
            if isinstance(value, (int, float)) and not isinstance(value, bool) and _numbers_only(field):
                out.append((f"values:{scene.stem}:{key}=string", [], _cmd(k, str(scene), "--set", f'{key}="{value!r}"'),
                            needle))
            elif isinstance(value, list) and value and all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                                           for v in value) and _list_of_numbers(field):
                items = ", ".join(['"1+2j"', *map(repr, value[1:])])
                out.append((f"values:{scene.stem}:{key}=complex_item", [], _cmd(k, str(scene), "--set",
                                                                                f"{key}=[{items}]"), needle))
            else:
                continue
            k += 1
    return out


def _intrinsic_cases() -> list:
    out, k = [], 0
    for scene in SCENES:
        cam = tomllib.loads(scene.read_text(encoding="utf-8")).get("camera", {})
        for key in ("fx", "fy", "cx", "cy", "skew", "skew_yx"):
            if key not in cam and key not in ("skew", "skew_yx"):
                continue
            if "fx" not in cam:
                continue
            for tag, v in (("e308", "1e308"), ("e20", "1e20")) + ((("ne308", "-1e308"),) if key not in ("fx", "fy") else ()):
                out.append((f"values:{scene.stem}:camera.{key}={tag}", [], _cmd(k, str(scene), "--set", f"camera.{key}={v}"),
                            key))
                k += 1
        if "fx" in cam:
            for coef in ("k1", "k2", "p1"):
                out.append((f"values:{scene.stem}:distortion.{coef}=e300", [],
                            _cmd(k, str(scene), "--set", 'camera.model="brown"', "--set", f"camera.distortion={{{coef} = 1e300}}"),
                            coef))
                k += 1
    return out


EPOCHS = ["0001-01-01T00:00:00Z", "1000-06-01T00:00:00Z", "1959-12-31T23:59:59Z", "2101-01-01T00:00:00Z",
          "9999-12-31T23:59:59Z"]


def _epoch_cases() -> list:
    from fuzz_cases import _leaves

    out, k = [], 0
    for scene in SCENES:
        data = tomllib.loads(scene.read_text(encoding="utf-8"))
        for path, _value in _leaves(data):
            if "epoch" not in path[-1]:
                continue
            key = ".".join(path)
            for epoch in EPOCHS:
                for quoted in (True, False):
                    v = f'"{epoch}"' if quoted else epoch
                    out.append((f"values:{scene.stem}:{key}={epoch[:4]}{'q' if quoted else ''}", [],
                                _cmd(k, str(scene), "--set", f"{key}={v}"), "year"))
                    k += 1
    return out


def _calibration_scene() -> str:
    text = tiny_scene_text()
    for line in ("fx = 33.0", "fy = 32.0", "cx = 16.4", "cy = 11.7", "width = 32", "height = 24", 'model = "pinhole"'):
        assert text.count(line) == 1, line
        text = text.replace(line, "", 1)
    return text.replace("[camera]", '[camera]\ncalibration_file = "calib.yaml"', 1)


CAL_K = "   data: [ 33.0, 0., 16.4, 0., 32.0, 11.7, 0., 0., 1. ]"


def _calibration_cases() -> list:
    from fuzz_files import CALIBRATION

    bad = [("fx_e308", "33.0,", "1e308,"), ("fx_neg", "33.0,", "-33.0,"), ("fx_nan", "33.0,", ".nan,"),
           ("fx_inf", "33.0,", ".inf,"), ("fx_complex", "33.0,", "1+2j,"), ("fx_complex_tag", "33.0,", "!!python/complex 1+2j,"),
           ("cx_e308", "16.4,", "1e308,"), ("fx_string_word", "33.0,", "thirty,")]
    out = []
    for tag, old, new in bad:
        cal = CALIBRATION.replace(CAL_K, CAL_K.replace(old, new, 1))
        assert cal != CALIBRATION
        out.append((f"values:calibration:{tag}", [["text", "s.toml", _calibration_scene()], ["text", "calib.yaml", cal]],
                    ["render", f"{CASE}/s.toml", "--out", f"{CASE}/out", "--dry-run"], "calib.yaml"))
    for coef, v in (("k1", "1e300"), ("p2", "-1e300"), ("k3", ".nan")):
        idx = ("k1", "k2", "p1", "p2", "k3").index(coef)
        vals = ["0.01", "0.", "0.", "0.", "0."]
        vals[idx] = v
        cal = CALIBRATION.replace("data: [ 0.01, 0., 0., 0., 0. ]", f"data: [ {', '.join(vals)} ]")
        out.append((f"values:calibration:D_{coef}", [["text", "s.toml", _calibration_scene()], ["text", "calib.yaml", cal]],
                    ["render", f"{CASE}/s.toml", "--out", f"{CASE}/out", "--dry-run"], "calib.yaml"))
    return out


MANIFEST_VALUES = [
    ("quat_zero", ["frames", 0, "pose", "quat_render_from_cam_xyzw"], [0.0, 0.0, 0.0, 0.0], "quat_render_from_cam_xyzw"),
    ("quat_tiny", ["frames", 0, "pose", "quat_render_from_cam_xyzw"], [1e-12, 0.0, 0.0, 0.0], "quat_render_from_cam_xyzw"),
    ("quat_complex", ["frames", 0, "pose", "quat_render_from_cam_xyzw"], ["1+2j", 0.0, 0.0, 1.0], "quat_render_from_cam_xyzw"),
    ("pos_nan", ["frames", 0, "pose", "position_m"], [math.nan, 0.0, 0.0], "position_m"),
    ("pos_e308", ["frames", 0, "pose", "position_m"], [1e308, 0.0, 0.0], "position_m"),
    ("pos_string", ["frames", 0, "pose", "position_m"], ["1.0", 0.0, 0.0], "position_m"),
    ("fx_e308", ["frames", 0, "camera", "fx"], 1e308, "fx"), ("fx_zero", ["frames", 0, "camera", "fx"], 0.0, "fx"),
    ("cy_e308", ["frames", 0, "camera", "cy"], -1e308, "cy"), ("width_string", ["frames", 0, "camera", "width"], "32", "width"),
    ("width_huge", ["frames", 0, "camera", "width"], 10 ** 9, "width"),
    ("k1_e308", ["frames", 0, "camera", "distortion"], {"k1": 1e308}, "k1"),
    ("time_e308", ["frames", 0, "time_s"], 1e308, "time_s"), ("time_nan", ["frames", 0, "time_s"], math.nan, "time_s"),
    ("time_complex", ["frames", 0, "time_s"], "1+2j", "time_s"),
    *[(f"epoch_{e[:4]}", ["frames", 0, "epoch_utc"], e, "epoch_utc") for e in EPOCHS],
    ("epoch_text", ["frames", 0, "epoch_utc"], "yesterday", "epoch_utc"),
]
APRIORI_VALUES = [
    ("quat_zero", ["images", 0, "quat_body_from_cam_xyzw"], [0.0, 0.0, 0.0, 0.0], "zero norm"),
    ("sun_zero", ["images", 0, "sun_direction_body"], [0.0, 0.0, 0.0], "sun_direction_body"),
    ("pos_nan", ["images", 0, "position_m"], [math.nan, 0.0, 5.0], "position_m"),
    ("pos_complex", ["images", 0, "position_m"], ["1+2j", 0.0, 5.0], "position_m"),
    ("fx_e308", ["camera", "fx"], 1e308, "fx"), ("cx_e308", ["camera", "cx"], 1e308, "cx"),
    ("width_string", ["camera", "width"], "32", "width"), ("bits_huge", ["bits"], 10 ** 30, "bits"),
    ("sigma_inf", ["images", 0, "position_sigma_m"], [math.inf, 0.1, 0.1], "position_sigma_m"),
]


def _maplet_hex(bad: str) -> str:
    """A 15 × 15 maplet EXR (the lab's writer) with one NaN or infinite height or albedo."""
    import tempfile
    from pathlib import Path

    import numpy as np

    from renderlab.files.imageio import write_exr

    h, a = np.zeros((15, 15)), np.full((15, 15), 0.2)
    {"nan_height": h, "inf_height": h, "nan_albedo": a}[bad][7, 7] = np.inf if bad.startswith("inf") else np.nan
    with tempfile.TemporaryDirectory() as d:
        write_exr(Path(d) / "m.exr", {"height": h, "albedo": a})
        return (Path(d) / "m.exr").read_bytes().hex()


def _catalog_cases() -> list:
    """NaN maplet heights and NaN catalogue numbers: refused before any landmark is measured."""
    measure = ["measure", "--images", f"{CASE}/apriori.json", "--catalog", f"{CASE}/cat", "--out", f"{CASE}/m.parquet",
               "--method", "retina"]
    base = [["copy", "apriori.json"], ["copy", "img.png"], ["copy", "cat"]]
    out = [(f"values:catalog:{bad}", [*base, ["bytes_hex", "cat/maplets/000001.exr", _maplet_hex(bad)]], measure,
            "finite") for bad in ("nan_height", "inf_height", "nan_albedo")]
    for col, needle in (("center_x_m", "centre"), ("center_z_m", "centre"), ("spacing_m", "spacing_m"),
                        ("q_body_from_maplet_w", "landmark 1")):
        out.append((f"values:catalog:{col}=nan", [*base, ["table", "cat/landmarks.parquet", "set_nan", col]], measure,
                    needle))
    return out


def values_cases(lab) -> list:
    out = _string_number_cases() + _intrinsic_cases() + _epoch_cases() + _calibration_cases() + _catalog_cases()
    ts_cmds = [["export", f"{CASE}/ts", "--oem", f"{CASE}/x.oem", "--epoch-utc", "2024-01-01T00:00:00"],
               ["info", f"{CASE}/ts"], ["measure", f"{CASE}/ts", "--method", "retina"]]
    for k, (tag, path, value, needle) in enumerate(MANIFEST_VALUES):
        out.append((f"values:manifest:{tag}", [["copy", "ts"], ["json", "ts/manifest.json", path, _json_value(value)]],
                    ts_cmds[k % 3], needle))
    measure = ["measure", "--images", f"{CASE}/apriori.json", "--catalog", f"{LAB}/cat", "--out", f"{CASE}/m.parquet",
               "--method", "retina", "--quiet"]
    for tag, path, value, needle in APRIORI_VALUES:
        out.append((f"values:apriori:{tag}", [["copy", "apriori.json"], ["copy", "img.png"],
                                              ["json", "apriori.json", path, _json_value(value)]], measure, needle))
    camp = ["campaign", f"{LAB}/scene.toml", "--runs", "1", "--out", f"{CASE}/c", "--scheduler", "tcp://127.0.0.1:9"]
    for v in ("1e308", "1e10", "3601", "inf", "nan", "-1", "0", "1e400", "1+2j"):
        out.append((f"values:connect_timeout={v}", [], [*camp, "--connect-timeout", v], "connect-timeout"))
    for flag, v in (("--n-sigma", "1e308"), ("--sigma-pos-m", "1e308"), ("--sigma-att-deg", "1e308"),
                    ("--psf-sigma-px", "1e308"), ("--max-search-px", str(10 ** 9)), ("--min-correlation", "1e308"),
                    ("--sigma-pos-m", "-1e308"), ("--n-sigma", "nan")):
        out.append((f"values:measure{flag}={v}", [], ["measure", f"{LAB}/ts", "--method", "retina", flag, v], flag))
    nav = ["navigation-budget", f"{LAB}/cat"]
    for flag, v in (("--runs", str(10 ** 9)), ("--runs", "1"), ("--seed", "-1"), ("--seed", str(2 ** 70))):
        out.append((f"values:navigation_budget{flag}={v}", [], [*nav, flag, v], flag))
    return out


# ------------------------------------------------------------------------------------------- resources
SLOTS = {  # slot → (setup, file the special goes to, argv, whether the message names the file's kind)
    "albedo_map": ([["copy", "scene.toml"]], "amap.png",
                   ["render", f"{CASE}/scene.toml", "--out", f"{CASE}/o", "--dry-run", "--set",
                    "world.bodies.0.albedo_map=amap.png"], True),
    "albedo_map_campaign": ([["copy", "scene.toml"]], "amap.png",
                            ["campaign", f"{CASE}/scene.toml", "--runs", "1", "--out", f"{CASE}/o", "--workers", "0",
                             "--set", "world.bodies.0.albedo_map=amap.png"], True),
    "mesh": ([["text", "s.toml", "MESH"]], "m.obj", ["render", f"{CASE}/s.toml", "--out", f"{CASE}/o", "--dry-run"], True),
    "calibration": ([["text", "s.toml", "CALIB"]], "calib.yaml",
                    ["render", f"{CASE}/s.toml", "--out", f"{CASE}/o", "--dry-run"], True),
    "trajectory": ([["copy", "scene.toml"]], "t.csv",
                   ["render", f"{CASE}/scene.toml", "--out", f"{CASE}/o", "--dry-run", "--set",
                    'trajectory={kind="table", file="t.csv", quaternion_order="xyzw", '
                    'quaternion_direction="cam_to_frame"}'], True),
    "apriori": ([["copy", "img.png"]], "apriori.json",
                ["measure", "--images", f"{CASE}/apriori.json", "--catalog", f"{LAB}/cat", "--out", f"{CASE}/m.parquet",
                 "--method", "retina"], True),
    "image": ([["copy", "apriori.json"]], "img.png",
              ["measure", "--images", f"{CASE}/apriori.json", "--catalog", f"{LAB}/cat", "--out", f"{CASE}/m.parquet",
               "--method", "retina"], True),
    "campaign_json": ([["copy", "camp"]], "camp/campaign.json", ["report", f"{CASE}/camp", "--out", f"{CASE}/r"], True),
    "status_json": ([["copy", "camp"]], "camp/runs/000000/status.json", ["info", f"{CASE}/camp"], True),
    "runs_json": ([["copy", "pub"]], "pub/runs.json", ["report", f"{CASE}/pub"], True),
    "manifest_json": ([["copy", "ts"]], "ts/manifest.json",
                      ["export", f"{CASE}/ts", "--oem", f"{CASE}/x.oem", "--epoch-utc", "2024-01-01T00:00:00"], True),
    "catalog_table": ([["copy", "apriori.json"], ["copy", "img.png"], ["copy", "cat"]], "cat/landmarks.parquet",
                      ["measure", "--images", f"{CASE}/apriori.json", "--catalog", f"{CASE}/cat", "--out",
                       f"{CASE}/m.parquet", "--method", "retina"], True),
}
KIND_WORDS = {"fifo": "FIFO", "zero": "character device", "urandom": "character device", "folder": "folder",
              "dangling": "not found", "loop": "symbolic links", "sparse": "MiB"}
BOX = 'shape = "box"\ncenter_m = [1.5, -0.6, 0.6]\nsize_m = [1.2, 1.2, 1.2]'


def _scene_text(marker: str) -> str:
    if marker == "MESH":
        return tiny_scene_text().replace(BOX, 'shape = "mesh"\nfile = "m.obj"\ncenter_m = [1.5, -0.6, 0.6]')
    if marker == "CALIB":
        from fuzz_families2 import _calibration_scene

        return _calibration_scene()
    return marker


def _special_cases() -> list:
    out = []
    for slot, (setup, target, argv, named) in SLOTS.items():
        setup = [[s[0], s[1], _scene_text(s[2])] if s[0] == "text" else s for s in setup]
        for kind, word in KIND_WORDS.items():
            out.append((f"resources:{slot}={kind}", [*setup, ["special", target, kind]], argv, word if named else ""))
    return out


def _bomb_cases() -> list:
    out = []
    for w, d in [(2, 17), (2, 24), (3, 11), (4, 9), (5, 8), (7, 6), (9, 6), (10, 5), (30, 4), (100, 3)]:
        out.append((f"resources:yaml_alias_bomb={w}x{d}", [["text", "s.toml", _calibration_scene_text()],
                                                          ["text", "calib.yaml", alias_bomb(w, d)]],
                    ["render", f"{CASE}/s.toml", "--out", f"{CASE}/o"], "alias"))
    mapping = ["a0: &a0 {x: 1, y: 2}"] + [f"a{k}: &a{k} {{p: *a{k - 1}, q: *a{k - 1}, r: *a{k - 1}}}" for k in range(1, 13)]
    others = {"mapping_bomb": "\n".join(mapping) + "\ncamera_matrix: *a12\n", "self_reference": "k: &k [1, *k]\n",
              "nested_deep": "camera_matrix: " + "[" * 20000 + "]" * 20000 + "\n"}
    for tag, text in others.items():
        out.append((f"resources:yaml_{tag}", [["text", "s.toml", _calibration_scene_text()], ["text", "calib.yaml", text]],
                    ["show", f"{CASE}/s.toml"], "calib.yaml"))
    return out


def _calibration_scene_text() -> str:
    from fuzz_families2 import _calibration_scene

    return _calibration_scene()


def _png(w: int, h: int) -> str:
    import cv2
    import numpy as np

    ok, buf = cv2.imencode(".png", np.zeros((h, w), np.uint16))
    assert ok
    return buf.tobytes().hex()


def _image_cases() -> list:
    out = []
    huge = [(65536, 1), (1, 65536), (20000, 20000), (2 ** 31 - 1, 2 ** 31 - 1), (0, 10), (100000, 100000)]
    measure = ["measure", "--images", f"{CASE}/apriori.json", "--catalog", f"{LAB}/cat", "--out", f"{CASE}/m.parquet",
               "--method", "retina"]
    for w, h in huge:
        for kind, data in (("png", png_header(w, h)), ("tiff", tiff_header(w, h)), ("fits", fits_header(w, h))):
            name = f"big.{'tif' if kind == 'tiff' else kind}"
            ap = apriori_data()
            ap["images"][0]["file"] = name
            out.append((f"resources:{kind}_header={w}x{h}:measure",
                        [["bytes_hex", name, data.hex()], ["text", "apriori.json", json.dumps(ap)]], measure,
                        "FITS" if kind == "fits" else "not an image" if kind == "tiff" and 0 in (w, h) else "px"))
            if kind != "fits":
                out.append((f"resources:{kind}_header={w}x{h}:albedo", [["copy", "scene.toml"], ["bytes_hex", name, data.hex()]],
                            ["render", f"{CASE}/scene.toml", "--out", f"{CASE}/o", "--dry-run", "--set",
                             f"world.bodies.0.albedo_map={name}"], "albedo_map"))
    for tag, b in (("fits_bitpix", fits_header(W, H, bitpix=7)), ("fits_short", fits_header(W, H, data_bytes=10))):
        ap = apriori_data()
        ap["images"][0]["file"] = "f.fits"
        out.append((f"resources:{tag}", [["bytes_hex", "f.fits", b.hex()], ["text", "apriori.json", json.dumps(ap)]],
                    measure, "FITS"))
    for w, h in [(W + 1, H), (W - 1, H), (W, H + 1), (W, H - 1), (H, W), (1, 1), (2 * W, 2 * H)]:
        out.append((f"resources:camera_size={w}x{h}", [["copy", "apriori.json"], ["bytes_hex", "img.png", _png(w, h)]],
                    measure, "a-priori camera"))
    return out


def resources_cases(lab) -> list:
    from renderlab.campaign.executors import WORKERS_PER_CORE, default_workers

    limit = WORKERS_PER_CORE * default_workers()
    out = _special_cases() + _bomb_cases() + _image_cases()
    for n in (limit + 1, 4 * limit, 100_000, 10 ** 9):
        out.append((f"resources:campaign_workers={n}", [], ["campaign", f"{LAB}/scene.toml", "--runs", "2", "--out",
                                                            f"{CASE}/c", "--workers", str(n)], "per core"))
        out.append((f"resources:navigation_budget_workers={n}", [], ["navigation-budget", f"{LAB}/cat", "--workers",
                                                                     str(n)], "per core"))
    return out
