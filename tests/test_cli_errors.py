"""User errors on the command line: exit code 2, one line on stderr, nothing written.

docs/architecture.md, "Command line": user errors exit with code 2 and one line on stderr. Each case
below is a small malformed scenario (the text of scenes/analytic_sphere_box.toml, shrunk to a
tiny render and then changed in one place) or a malformed argument list. Every case checks:

* exit code 2;
* exactly one non-empty line on stderr, ``renderlab: error: ...``, naming the problem;
* no traceback anywhere;
* no output folder and no hidden staging folder left behind (an existing folder is untouched).

Most cases run in-process through :func:`renderlab.cli.main`; a few go through a real
``renderlab`` subprocess, and one subprocess runs every case to prove that none of them (bar a
corrupt mesh, which only Mitsuba can read) imports mitsuba or drjit before failing.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from renderlab.cli import main

REPO = Path(__file__).resolve().parents[1]
RENDERLAB = Path(sys.executable).parent / "renderlab"  # the console script of the environment running the tests
PYTHON = Path(sys.executable)
SCENE = REPO / "scenes" / "analytic_sphere_box.toml"
PREFIX = "renderlab: error: "


def _sub(text: str, old: str, new: str) -> str:
    assert text.count(old) == 1, f"test setup: {old!r} must occur exactly once"
    return text.replace(old, new)


def _tiny_text() -> str:
    """scenes/analytic_sphere_box.toml shrunk to a 24x18 camera, 2 spp, 2 frames."""
    t = SCENE.read_text(encoding="utf-8")
    for old, new in [("width = 256", "width = 24"), ("height = 192", "height = 18"),
                     ("fx = 262.0", "fx = 26.0"), ("fy = 258.0", "fy = 25.0"),
                     ("cx = 131.3", "cx = 11.5"), ("cy = 93.8", "cy = 8.5"),
                     ("frames = 4", "frames = 2"), ("spp = 16", "spp = 2")]:
        t = _sub(t, old, new)
    return t


TINY = _tiny_text()
BOX = 'shape = "box"\ncenter_m = [1.5, -0.6, 0.6]\nsize_m = [1.2, 1.2, 1.2]'


def edit(old: str, new: str):
    """A scenario-text case: TINY with one replacement."""
    return lambda: _sub(TINY, old, new)


# name → (scenario text or callable giving it, or None for the valid tiny scenario;
#         extra argv; distinctive substring of the error line)
SCENARIO_CASES = {
    "not_toml": ("name = \"x\"\n[camera\nwidth = 3\n", [], "not valid TOML"),
    "not_text": (b"\xff\xfe\x00\x81 binary", [], "not a text file"),
    "missing_world": (lambda: TINY.split("[world]")[0] + "[sun]" + TINY.split("[sun]", 1)[1], [],
                      "missing key 'world'"),
    "unknown_top_level_key": (edit('name = "analytic_sphere_box"', 'name = "analytic_sphere_box"\ncolour = "red"'),
                              [], "unknown key 'colour'"),
    "unknown_nested_key": (edit("fx = 26.0", "fx = 26.0\nfocal = 3.0"), [], "unknown key 'camera.focal'"),
    "negative_focal_length": (edit("fx = 26.0", "fx = -26.0"), [], "camera.fx"),
    "zero_width": (edit("width = 24", "width = 0"), [], "camera.width"),
    "nan_value": (edit("fy = 25.0", "fy = nan"), [], "camera.fy"),
    "inf_value": (edit("irradiance_w_m2 = 1361.0", "irradiance_w_m2 = inf"), [], "sun.irradiance_w_m2"),
    "wrong_type": (edit("range_m = 11.0", 'range_m = "eleven"'), [], "trajectory.range_m"),
    "unknown_law": (edit('law = "lommel_seeliger"', 'law = "minnaert"'), [], "world.bodies.2.law"),
    "unknown_law_param": (edit("albedo = 0.5", "albedo = 0.5\nlaw_params = {roughness = 0.3}"), [],
                          "'roughness'"),
    "unknown_shape": (edit('shape = "box"', 'shape = "torus"'), [], "world.bodies.2.shape"),
    "sphere_without_radius": (edit("radius_m = 1.0\n", ""), [], "radius_m"),
    "albedo_above_one": (edit("albedo = 0.5", "albedo = 1.5"), [], "world.bodies.1.albedo"),
    "unknown_sensor_key": (edit("auto_exposure = true", "auto_exposure = true\nfoo_gain = 2.0"), [],
                           "unknown sensor key 'foo_gain'"),
    "bad_sensor_value": (edit("auto_exposure = true", "auto_exposure = true\nbits = 20"), [], "sensor.bits"),
    "bad_brown_distortion_key": (edit('model = "pinhole"', 'model = "brown"\ndistortion = {k1 = 0.01, q9 = 0.2}'),
                                 [], "q9"),
    "unknown_camera_model": (edit('model = "pinhole"', 'model = "fisheye"'), [], "camera.model"),
    "duplicate_body_names": (edit('name = "box"', 'name = "sphere"'), [], "body names must be unique"),
    "far_clip_below_near": (edit("far_clip_m = 1000.0", "far_clip_m = 0.001"), [], "far_clip_m"),
    "unknown_variant": (edit('variant = "llvm_ad_mono"', 'variant = "optix_rgb"'), [], "render.variant"),
    "zero_sun_direction": (edit("direction = [0.55, -0.35, 0.76]", "direction = [0.0, 0.0, 0.0]"), [],
                           "sun direction"),
    "elevation_90": (edit("elevation_deg = 35.0", "elevation_deg = 90.0"), [], "trajectory.elevation_deg"),
    "line_without_start": (edit('kind = "orbit"', 'kind = "line"'), [], "start_m"),
    "camera_on_target": (edit('kind = "orbit"', 'kind = "line"\nstart_m = [0.0, 0.0, 0.6]'), [],
                         "puts the camera on its target"),
    "missing_albedo_map": (edit("albedo = 0.5", 'albedo = 0.5\nalbedo_map = "missing_albedo.png"'), [],
                           "missing_albedo.png"),
    "unreadable_albedo_map": (edit("albedo = 0.5", 'albedo = 0.5\nalbedo_map = "fake.png"'), [], "fake.png"),
    "mesh_wrong_extension": (edit(BOX, 'shape = "mesh"\nfile = "rock.xyz"\ncenter_m = [1.5, -0.6, 0.6]'), [],
                             "rock.xyz"),
    "mesh_without_faces": (edit(BOX, 'shape = "mesh"\nfile = "rock.stl"\ncenter_m = [1.5, -0.6, 0.6]'), [],
                           "rock.stl has no faces"),
    "mesh_missing": (edit(BOX, 'shape = "mesh"\nfile = "nowhere.obj"\ncenter_m = [1.5, -0.6, 0.6]'), [],
                     "mesh not found"),
    "cycles_direct_light_only": (edit("max_depth = 2", "max_depth = 3"), ["--renderer", "cycles"],
                                 "render.max_depth must be 2"),
    # --- arguments, on the valid tiny scenario
    "set_without_equals": (None, ["--set", "camera.width"], "--set expects KEY=VALUE"),
    "set_empty_key": (None, ["--set", "=3"], "empty key"),
    "set_unknown_key": (None, ["--set", "camera.zoom=2"], "unknown key 'camera.zoom'"),
    "set_bad_value": (None, ["--set", "camera.width=wide"], "camera.width"),
    "set_negative_value": (None, ["--set", "render.spp=-4"], "render.spp"),
    "set_no_list_item": (None, ["--set", "world.bodies.7.radius_m=2"], "no list item 7"),
    "set_into_scalar": (None, ["--set", "camera.width.x=2"], "'width' is not a table"),
    "frames_zero": (None, ["--frames", "0"], "--frames"),
    "seed_negative": (None, ["--seed", "-1"], "--seed"),
    "seed_not_a_number": (None, ["--seed", "abc"], "--seed"),
    "unknown_renderer": (None, ["--renderer", "povray"], "povray"),
    "unknown_option": (None, ["--bogus"], "--bogus"),
}
# Mitsuba alone can tell that a mesh file is corrupt: this case may import it (run last).
CORRUPT_MESH = ("corrupt_mesh", edit(BOX, 'shape = "mesh"\nfile = "broken.obj"\ncenter_m = [1.5, -0.6, 0.6]'),
                [], "broken.obj")


def _write_assets(d: Path) -> None:
    (d / "rock.stl").write_text("solid rock\nendsolid rock\n")
    (d / "rock.xyz").write_text("0 0 0\n1 0 0\n0 1 0\n")
    (d / "fake.png").write_bytes(b"this is not a PNG")
    (d / "broken.obj").write_text("v 1 2\nf 1 2 3\n")


def build_scenario_case(d: Path, name: str, spec) -> tuple[list[str], Path, str]:
    """Write the case's files under ``d``; return (argv, output folder, needle)."""
    text, extra, needle = spec
    d.mkdir(parents=True, exist_ok=True)
    _write_assets(d)
    text = TINY if text is None else (text() if callable(text) else text)
    scen = d / f"{name}.toml"
    if isinstance(text, bytes):
        scen.write_bytes(text)
    else:
        scen.write_text(text, encoding="utf-8")
    out = d / "out"
    return ["render", str(scen), "--out", str(out), "--quiet", *extra], out, needle


def build_other_case(d: Path, name: str) -> tuple[list[str], Path, str]:
    """Cases about the command, the scenario path or the output folder."""
    d.mkdir(parents=True, exist_ok=True)
    scen = d / "tiny.toml"
    scen.write_text(TINY, encoding="utf-8")
    out = d / "out"
    if name == "missing_scenario_file":
        return ["render", str(d / "no_such_scenario.toml"), "--out", str(out)], out, "no_such_scenario.toml"
    if name == "unknown_command":
        return ["paint", str(scen), "--out", str(out)], out, "paint"
    if name == "no_command":
        return [], out, "command"
    if name == "missing_out":
        return ["render", str(scen)], out, "--out"
    if name == "missing_scenario_and_out":
        return ["render"], out, "SCENARIO"
    if name == "out_under_regular_file":
        blocker = d / "blocker"
        blocker.write_text("a regular file\n")
        out = blocker / "sub" / "set"
        return ["render", str(scen), "--out", str(out), "--quiet"], out, "blocker"
    if name == "out_is_a_file":
        out.write_text("not a folder\n")
        return ["render", str(scen), "--out", str(out), "--quiet"], out, "not a directory"
    if name == "out_exists_nonempty":
        out.mkdir()
        (out / "keep.txt").write_text("precious\n")
        return ["render", str(scen), "--out", str(out), "--quiet"], out, "not empty"
    raise KeyError(name)


OTHER_CASES = ["missing_scenario_file", "unknown_command", "no_command", "missing_out",
               "missing_scenario_and_out", "out_under_regular_file", "out_is_a_file", "out_exists_nonempty"]


def build_case(d: Path, name: str):
    if name in SCENARIO_CASES:
        return build_scenario_case(d, name, SCENARIO_CASES[name])
    if name == CORRUPT_MESH[0]:
        return build_scenario_case(d, name, CORRUPT_MESH[1:])
    return build_other_case(d, name)


ALL_CASES = [*SCENARIO_CASES, *OTHER_CASES, CORRUPT_MESH[0]]


def _snapshot(path: Path):
    """What exists at ``path`` (None, a file's bytes, or a folder's {relpath: bytes})."""
    if not os.path.lexists(path):
        return None
    if path.is_file():
        return path.read_bytes()
    return {str(p.relative_to(path)): (p.read_bytes() if p.is_file() else None) for p in sorted(path.rglob("*"))}


def assert_user_error(rc, stdout: str, stderr: str, needle: str, d: Path, out: Path, before) -> None:
    assert rc == 2, f"exit code {rc}, stderr={stderr!r}"
    assert "Traceback" not in stderr and "Traceback" not in stdout, stderr
    lines = stderr.splitlines()
    assert len(lines) == 1, f"expected one line on stderr, got {lines!r}"
    line = lines[0]
    assert line.startswith(PREFIX), line
    assert line[len(PREFIX):].strip(), "empty error message"
    assert needle in line, f"{needle!r} not in {line!r}"
    assert _snapshot(out) == before, f"output {out} was created or changed"
    leftovers = [p.name for p in d.rglob(".*")]
    assert not leftovers, f"hidden staging folders left behind: {leftovers}"


def test_tiny_scenario_is_valid(tmp_path, capsys):
    """Control: the unmodified tiny scenario renders, so each case below fails for its own reason."""
    scen = tmp_path / "tiny.toml"
    scen.write_text(TINY, encoding="utf-8")
    rc = main(["render", str(scen), "--out", str(tmp_path / "out"), "--quiet"])
    cap = capsys.readouterr()
    assert rc == 0, cap.err
    assert (tmp_path / "out" / "manifest.json").is_file()
    assert len(json.loads((tmp_path / "out" / "manifest.json").read_text())["frames"]) == 2


@pytest.mark.parametrize("name", ALL_CASES)
def test_user_error_in_process(name, tmp_path, capsys):
    argv, out, needle = build_case(tmp_path, name)
    before = _snapshot(out)
    rc = main(argv)
    cap = capsys.readouterr()
    assert_user_error(rc, cap.out, cap.err, needle, tmp_path, out, before)


@pytest.mark.parametrize("name", ["missing_scenario_file", "unknown_command", "set_without_equals",
                                  "out_exists_nonempty", "nan_value"])
def test_user_error_subprocess(name, tmp_path):
    """End to end through the installed ``renderlab`` script."""
    argv, out, needle = build_case(tmp_path, name)
    before = _snapshot(out)
    proc = subprocess.run([str(RENDERLAB), *argv], capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert_user_error(proc.returncode, proc.stdout, proc.stderr, needle, tmp_path, out, before)


def test_python_dash_m_entry_point(tmp_path):
    argv, out, needle = build_case(tmp_path, "unknown_nested_key")
    proc = subprocess.run([str(PYTHON), "-m", "renderlab", *argv], capture_output=True, text=True,
                          timeout=120, cwd=REPO)
    assert_user_error(proc.returncode, proc.stdout, proc.stderr, needle, tmp_path, out, None)


_NO_HEAVY_IMPORTS = r"""
import contextlib, io, json, sys
from renderlab.cli import main
result = []
for name, argv in json.loads(sys.argv[1]):
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        rc = main(argv)
    result.append([name, rc, "mitsuba" in sys.modules or "drjit" in sys.modules])
print(json.dumps(result))
"""


def test_errors_fail_before_importing_mitsuba(tmp_path):
    """All cases in one fresh interpreter; only the corrupt mesh (run last) may import mitsuba."""
    cases = [(name, build_case(tmp_path / name, name)[0]) for name in ALL_CASES]
    proc = subprocess.run([str(PYTHON), "-c", _NO_HEAVY_IMPORTS, json.dumps(cases)], capture_output=True,
                          text=True, timeout=120, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout.splitlines()[-1])
    assert [r[0] for r in result] == ALL_CASES
    assert all(rc == 2 for _, rc, _ in result), result
    heavy = [name for name, _, imported in result if imported and name != CORRUPT_MESH[0]]
    assert not heavy, f"these cases imported mitsuba/drjit before failing: {heavy}"


def test_case_count():
    """The brief asks for at least 24 distinct cases."""
    assert len(set(ALL_CASES)) >= 24
