"""Packaging: the wheel carries the built-in scenes, the OSL shader and the report template, and the demo's first
stage runs from a fresh venv installed from it (not from the checkout); ranges in pyproject, exact pins in
requirements.lock; a missing extra is a one-line error naming it; a CUDA variant without a GPU falls back to LLVM.

The fresh venv gets the wheel with ``--no-deps --no-index`` and the lab's dependencies through a ``.pth`` line
naming this environment's site-packages (a plain path: the checkout's editable finder there stays inactive), so
nothing is downloaded. ``--no-build-isolation`` needs setuptools >= 77 in this environment (``./setup.sh``).
"""

from __future__ import annotations

import json
import os
import shutil
import site
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

from renderlab.errors import UserError

REPO = Path(__file__).resolve().parents[1]
#: the analytic scene's 256 x 192 camera shrunk 8x, one frame, one sample per pixel
TINY = ["--frames", "1", "--set", "render.spp=1"] + [a for kv in ("camera.width=32", "camera.height=24", "camera.fx=32.75",
                                                     "camera.fy=32.25", "camera.cx=16.4", "camera.cy=11.7")
                                                    for a in ("--set", kv)]
#: runs the CLI with the modules named in argv[1] (comma-separated) made unimportable
BLOCKED_CLI = ("import sys\nfor m in sys.argv[1].split(','): sys.modules[m] = None\n"
               "from renderlab.cli import main\nsys.exit(main(sys.argv[2:]))")


def _package_data() -> list[str]:
    """Every non-Python file of the renderlab package in the checkout (what the wheel must carry)."""
    root = REPO / "renderlab"
    return sorted(str(p.relative_to(REPO)) for p in root.rglob("*")
                  if p.is_file() and p.suffix not in (".py", ".pyc") and "__pycache__" not in p.parts)


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    """The wheel, built offline from a copy of the checkout (the build writes nothing into the checkout)."""
    import setuptools

    if tuple(int(x) for x in setuptools.__version__.split(".")[:2]) < (77, 0):
        pytest.fail(f"setuptools {setuptools.__version__} < 77 cannot build the wheel offline; run ./setup.sh")
    tmp = tmp_path_factory.mktemp("wheel")
    src = tmp / "src"
    skip = shutil.ignore_patterns("__pycache__", "*.pyc", "*.egg-info")
    for d in ("renderlab", "estimators"):
        shutil.copytree(REPO / d, src / d, ignore=skip)
    for f in ("pyproject.toml", "README.md"):
        shutil.copy2(REPO / f, src / f)
    proc = subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "--no-build-isolation",
                           "--no-index", "-w", str(tmp / "dist"), str(src)], capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    (whl,) = (tmp / "dist").glob("renderlab-*.whl")
    return whl


def test_the_wheel_carries_the_scenes_the_shader_and_every_data_file(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    data = _package_data()
    assert "renderlab/render/osl/rl_photometry.osl" in data and "renderlab/scenes/analytic_sphere_box.toml" in data
    assert [f for f in data if f not in names] == []
    meta = zipfile.ZipFile(wheel).read(next(n for n in names if n.endswith(".dist-info/METADATA"))).decode()
    assert 'Requires-Dist: bpy<5.1,>=5.0; extra == "cycles"' in meta
    assert "Requires-Dist: numpy<2,>=1.26" in meta


def test_scenes_of_the_checkout_link_to_the_package_folder():
    from renderlab.builtin import SCENES_DIR, scene_names, scene_path

    assert (REPO / "scenes").is_symlink() and (REPO / "scenes").resolve() == (REPO / "renderlab" / "scenes")
    assert SCENES_DIR.resolve() == REPO / "renderlab" / "scenes"
    assert "analytic_sphere_box.toml" in scene_names() and scene_path("coastline_ekf.toml").is_file()
    with pytest.raises(UserError, match="built-in scenario nope.toml not found"):
        scene_path("nope.toml")


@pytest.fixture(scope="module")
def wheel_venv(wheel, tmp_path_factory) -> Path:
    """A fresh venv with only the wheel installed; the dependencies come from this environment (a .pth line)."""
    venv = tmp_path_factory.mktemp("venv") / "env"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True, timeout=300)
    proc = subprocess.run([str(venv / "bin" / "python"), "-m", "pip", "install", "-q", "--no-deps", "--no-index",
                           str(wheel)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    purelib = subprocess.run([str(venv / "bin" / "python"), "-c", "import sysconfig; print(sysconfig.get_paths()"
                              "['purelib'])"], capture_output=True, text=True, check=True).stdout.strip()
    (Path(purelib) / "zz_renderlab_test_deps.pth").write_text("\n".join(site.getsitepackages()) + "\n")
    return venv


def _clean_env() -> dict:
    return {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")} | {"MPLBACKEND": "Agg"}


_WHERE = """
import json, sys, renderlab
from renderlab.builtin import scene_path
from renderlab.render.cycles_backend import OSL_PATH
print(json.dumps({"renderlab": renderlab.__file__, "scene": str(scene_path("analytic_sphere_box.toml")),
                  "osl": str(OSL_PATH), "osl_ok": OSL_PATH.is_file(), "prefix": sys.prefix}))
"""

_CHECK = """
import json, sys
from renderlab.report.truth_checks import check_frame
from renderlab.scenario import load_scenario
from renderlab.files.truthset import TruthSet
from renderlab.builtin import scene_path
scenario, _ = load_scenario(scene_path("analytic_sphere_box.toml"))
ts = TruthSet.open(sys.argv[1])
lambert = {k: b.albedo for k, b in enumerate(scenario.world.bodies) if b.law == "lambert" and not b.albedo_map}
c = check_frame(ts.load(0), lambert)
print(json.dumps({"frames": len(ts), "n_hit": c.n_hit, "reproj_max_px": c.reproj_max_px, "variant":
                  ts.manifest["renderer"]["variant"]}))
"""


def test_the_demo_first_stage_runs_from_a_venv_installed_from_the_wheel(wheel_venv, tmp_path):
    py, env = str(wheel_venv / "bin" / "python"), _clean_env()
    where = json.loads(subprocess.run([py, "-c", _WHERE], cwd=tmp_path, env=env, capture_output=True, text=True,
                                      check=True, timeout=120).stdout)
    for key in ("renderlab", "scene", "osl"):
        assert Path(where[key]).is_relative_to(wheel_venv), where  # the wheel's files, not the checkout's
        assert not Path(where[key]).resolve().is_relative_to(REPO), where
    assert where["osl_ok"], where
    out = tmp_path / "truthset"
    proc = subprocess.run([str(wheel_venv / "bin" / "renderlab"), "render", where["scene"], "--out", str(out),
                           "--quiet", *TINY], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    res = json.loads(subprocess.run([py, "-c", _CHECK, str(out)], cwd=tmp_path, env=env, capture_output=True,
                                    text=True, check=True, timeout=300).stdout)
    assert res["frames"] == 1 and res["n_hit"] > 100 and res["reproj_max_px"] < 1e-3, res  # the demo's checks


def test_cycles_renders_from_the_wheel_with_its_shader(wheel_venv, tmp_path):
    pytest.importorskip("bpy")
    proc = subprocess.run([str(wheel_venv / "bin" / "renderlab"), "render", "--quiet", "--renderer", "cycles",
                           str(REPO / "scenes" / "analytic_sphere_box.toml"), "--out", str(tmp_path / "cy"), *TINY],
                          cwd=tmp_path, env=_clean_env(), capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert (tmp_path / "cy" / "manifest.json").is_file()


def _pins() -> dict[str, str]:
    lines = (REPO / "requirements.lock").read_text().splitlines()
    return {canonicalize_name(n): v for n, _, v in (ln.partition("==") for ln in lines if "==" in ln)}


def test_pyproject_has_ranges_and_the_lock_pins_every_dependency_inside_them():
    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    extras = project["optional-dependencies"]
    assert {"cycles", "earth", "cluster", "spice", "all", "test"} <= set(extras)
    reqs = [Requirement(r) for r in project["dependencies"] + [r for rs in extras.values() for r in rs]]
    reqs = [r for r in reqs if canonicalize_name(r.name) != "renderlab"]
    assert [str(r) for r in reqs if any(s.operator == "==" for s in r.specifier)] == []  # ranges, not pins
    assert "bpy" not in {canonicalize_name(Requirement(r).name) for r in project["dependencies"]}
    pins = _pins()
    unpinned = [r.name for r in reqs if canonicalize_name(r.name) not in pins]
    outside = [f"{r} (locked {pins[canonicalize_name(r.name)]})" for r in reqs
               if canonicalize_name(r.name) in pins and not r.specifier.contains(pins[canonicalize_name(r.name)])]
    assert (unpinned, outside) == ([], [])
    assert pins["numpy"].startswith("1.") and int(pins["setuptools"].split(".")[0]) >= 77
    assert '-c "$LOCK"' in (REPO / "setup.sh").read_text() and ".[all,test]" in (REPO / "setup.sh").read_text()


@pytest.mark.parametrize("blocked, argv, extra", [
    ("bpy", ["render", "scenes/analytic_sphere_box.toml", "--renderer", "cycles", *TINY], "cycles"),
    ("bpy", ["crosscheck", "scenes/analytic_sphere_box.toml", *TINY], "cycles"),
    ("roaring_landmask", ["render", "scenes/earth_leo.toml", "--frames", "1", "--set", "render.spp=1", "--set",
                          "camera.width=32", "--set", "camera.height=24"], "earth"),  # its FOV is trajectory.fov_deg
    ("shapely", ["campaign", "scenes/coastline_ekf.toml", "--runs", "1", "--workers", "0"], "earth"),
    ("roaring_landmask", ["visibility", "--hours", "0.5"], "earth"),
    ("distributed,dask", ["campaign", "scenes/analytic_sphere_box.toml", "--runs", "2", "--workers", "2"], "cluster"),
])
def test_a_missing_extra_is_one_line_naming_it_and_nothing_is_made(blocked, argv, extra, tmp_path):
    out = tmp_path / "out"
    argv = [str(REPO / a) if a.startswith("scenes/") else a for a in argv]
    proc = subprocess.run([sys.executable, "-c", BLOCKED_CLI, blocked, *argv, "--out", str(out)], cwd=tmp_path,
                          env=_clean_env(), capture_output=True, text=True, timeout=300)
    lines = [ln for ln in proc.stderr.splitlines() if ln.startswith("renderlab:")]
    assert proc.returncode == 2 and len(lines) == 1, proc.stderr[-2000:]
    assert f"needs the '{extra}' extra (pip install \"renderlab[{extra}]\")" in lines[0], lines
    assert "Traceback" not in proc.stderr and not out.exists()


def test_require_imports_or_names_the_extra(monkeypatch):
    from renderlab.extras import require
    from renderlab.trajectory_io.spice import read_spice

    assert require("json", "cluster") is json
    monkeypatch.setitem(sys.modules, "spiceypy", None)
    with pytest.raises(UserError, match=r"""a SPICE trajectory needs the 'spice' extra \(pip install "renderlab\[spice\]"\)"""):
        read_spice([], observer="-1", center="EARTH", frame="J2000", camera_frame=None, epoch_utc="2030-01-01T00:00:00",
                   times_s=[0.0])
    with pytest.raises(UserError, match="the Cycles renderer needs the 'cycles' extra"):
        require("renderlab_no_such_module", "cycles", load=False)


def test_fallback_chain_of_variants():
    from renderlab.render.variant import fallbacks

    assert fallbacks("cuda_ad_mono") == ["llvm_ad_mono", "scalar_rgb"]
    assert fallbacks("cuda_ad_rgb") == ["llvm_ad_rgb", "scalar_rgb"]
    assert fallbacks("llvm_ad_mono") == ["scalar_rgb"] and fallbacks("scalar_rgb") == []


_CUDA = """
import json, warnings
from renderlab.render.variant import init_mitsuba
with warnings.catch_warnings(record=True) as w:
    warnings.simplefilter("always")
    mi = init_mitsuba("cuda_ad_mono")
    again = init_mitsuba("cuda_ad_mono").variant()
print(json.dumps({"variant": mi.variant(), "again": again, "warnings": [str(x.message) for x in w]}))
"""


def test_a_cuda_variant_without_a_gpu_falls_back_to_llvm_not_scalar():
    res = json.loads(subprocess.run([sys.executable, "-c", _CUDA], capture_output=True, text=True, check=True,
                                    timeout=300, env=_clean_env()).stdout.splitlines()[-1])
    if res["variant"] == "cuda_ad_mono":
        pytest.skip("this machine has a usable CUDA GPU")
    assert res["variant"] == res["again"] == "llvm_ad_mono", res
    (msg,) = res["warnings"]  # once per process
    assert "cuda_ad_mono is not usable here (cuda_ad_mono: no usable CUDA GPU or driver" in msg
    assert msg.endswith("falling back to llvm_ad_mono (CPU)") and "libllvm19" not in msg, msg
