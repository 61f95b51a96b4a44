"""Determinism and round trips of ``renderlab render`` (tiny renders of scenes/analytic_sphere_box.toml).

* The same seed gives byte-identical truth sets (manifest, every EXR and PNG), in one process
  and across processes.
* A different seed changes the sensor noise (DN PNGs) but not the truth AOVs (position, normal,
  range, id come from one ray through each pixel centre).
* A written truth set reads back (``TruthSet``) to exactly what the backend produced, frame by
  frame, when the frame is re-rendered alone with the pipeline's seed derivation; the manifest's
  camera, pose and sun agree with the scenario, and the position AOV re-projects onto the pixel
  centres through the manifest's camera and pose.
* Scalar fallback: with Dr.Jit pointed at a missing libLLVM, a ``llvm_ad_mono`` scenario renders
  with ``scalar_rgb`` (RuntimeWarning on stderr, exit 0, manifest says so) and agrees with the
  LLVM render (centre sampling) to 1e-4 relative on lit pixels.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from renderlab.cli import main

REPO = Path(__file__).resolve().parents[1]
RENDERLAB = Path(sys.executable).parent / "renderlab"  # the console script of the environment running the tests
SCENE = REPO / "scenes" / "analytic_sphere_box.toml"
TINY_SET = ["camera.width=24", "camera.height=18", "camera.fx=26", "camera.fy=25", "camera.cx=11.5",
            "camera.cy=8.5", "render.spp=2"]
N_FRAMES = 2
TINY = [a for kv in TINY_SET for a in ("--set", kv)] + ["--frames", str(N_FRAMES), "--quiet"]


def _render(out: Path, *extra: str) -> Path:
    rc = main(["render", str(SCENE), "--out", str(out), *TINY, *extra])
    assert rc == 0
    return out


def _files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def _manifest(root: Path) -> dict:
    return json.loads((root / "manifest.json").read_text(encoding="utf-8"))


@pytest.fixture(scope="module")
def sets(tmp_path_factory):
    """Three tiny truth sets: A and B with seed 3, C with seed 4."""
    d = tmp_path_factory.mktemp("determinism")
    return {"A": _render(d / "A", "--seed", "3"), "B": _render(d / "B", "--seed", "3"),
            "C": _render(d / "C", "--seed", "4")}


# ----------------------------------------------------------------------------- (a) same seed
def test_same_seed_byte_identical(sets):
    a, b = _files(sets["A"]), _files(sets["B"])
    expected = ({"manifest.json", "contact_sheet.png"} | {f"dn_preview/{k:06d}.png" for k in range(N_FRAMES)}
                | {f"frames/{k:06d}.{ext}" for k in range(N_FRAMES) for ext in ("exr", "png")})
    assert set(a) == expected
    assert set(b) == expected
    for name in sorted(expected):
        assert a[name] == b[name], f"{name} differs between two renders with seed 3"
    assert _manifest(sets["A"])["seed"] == 3


def test_same_seed_byte_identical_across_processes(sets, tmp_path):
    """A fresh interpreter (fresh JIT, fresh kernel cache) writes the same bytes."""
    out = tmp_path / "P"
    proc = subprocess.run([str(RENDERLAB), "render", str(SCENE), "--out", str(out), *TINY, "--seed", "3"],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    a, p = _files(sets["A"]), _files(out)
    assert set(a) == set(p)
    for name in sorted(a):
        assert a[name] == p[name], f"{name} differs between in-process and subprocess renders"


# ------------------------------------------------------------------------ (b) different seed
def test_different_seed_changes_noise_not_truth(sets):
    from renderlab.files.truthset import TruthSet

    a, c = TruthSet.open(sets["A"]), TruthSet.open(sets["C"])
    assert len(a) == len(c) == N_FRAMES
    fa, fc = _files(sets["A"]), _files(sets["C"])
    for k in range(N_FRAMES):
        assert fa[f"frames/{k:06d}.png"] != fc[f"frames/{k:06d}.png"], f"frame {k}: DN PNG did not change"
        xa, xc = a.load(k), c.load(k)
        assert np.count_nonzero(xa.dn != xc.dn) > xa.dn.size // 10, "sensor noise barely changed"
        assert np.any(xa.radiance != xc.radiance), "the seed should move the sub-pixel samples"
        np.testing.assert_array_equal(xa.position, xc.position)  # NaN == NaN here
        np.testing.assert_array_equal(xa.normal, xc.normal)
        np.testing.assert_array_equal(xa.range, xc.range)
        np.testing.assert_array_equal(xa.id, xc.id)
        assert np.isfinite(xa.position).all(axis=-1).sum() > xa.id.size // 2, "too few hits to be a test"
        assert xa.meta["camera"] == xc.meta["camera"] and xa.meta["pose"] == xc.meta["pose"]
    ma, mc = _manifest(sets["A"]), _manifest(sets["C"])
    assert (ma["seed"], mc["seed"]) == (3, 4)
    # The manifest's scenario records the seed actually used; everything else is the same.
    assert (ma["scenario"]["render"].pop("seed"), mc["scenario"]["render"].pop("seed")) == (3, 4)
    assert ma["scenario"] == mc["scenario"]


# ------------------------------------------------------------------------------- (c) round trip
def test_truthset_round_trip_matches_backend(sets):
    """Re-render each frame alone (pipeline seed derivation) and compare with what was read back."""
    from renderlab.files.imageio import read_exr
    from renderlab.files.truthset import AOV_CHANNELS, TruthSet
    from renderlab.geometry.camera import CameraModel
    from renderlab.geometry.rotations import rotation_from_quat_xyzw
    from renderlab.pipeline import frame_specs, make_backend
    from renderlab.scenario import load_scenario
    from renderlab.sensor.model import SensorOptions, expose, exposure_for_peak, with_exposure
    from renderlab.worlds.analytic import build_scene

    seed = 3
    sc, base = load_scenario(SCENE, TINY_SET)
    backend = make_backend(sc, build_scene(sc.world, base), "mitsuba")
    specs = frame_specs(sc)[:N_FRAMES]
    ts = TruthSet.open(sets["A"])
    m = ts.manifest
    assert m["format"] == "renderlab.truthset/1"
    assert m["renderer"] == {"name": "mitsuba", "version": backend.version, "variant": backend.variant}
    expected = sc.to_dict()
    expected["render"]["seed"] = seed  # --seed overrides the file's render.seed and is recorded
    assert m["scenario"] == expected
    assert len(ts) == N_FRAMES

    base = SensorOptions(**sc.sensor.options_dict())
    opts = base
    children = np.random.SeedSequence(seed).spawn(N_FRAMES)
    for spec, child in zip(specs, children):
        k = spec.index
        render_ss, sensor_ss = child.spawn(2)
        direct = backend.render(spec, seed=int(render_ss.generate_state(1)[0]))
        if k == 0 and sc.sensor.auto_exposure:  # chosen on the first frame, kept
            opts = with_exposure(base, exposure_for_peak(direct.radiance, base,
                                                         fraction=sc.sensor.auto_exposure_fraction))
        dn = expose(direct.radiance, opts, np.random.default_rng(sensor_ss)).dn

        fr = ts.load(k)
        # arrays: read back == produced (float32 on disk; range is float64 in memory)
        np.testing.assert_array_equal(fr.radiance, direct.radiance)
        np.testing.assert_array_equal(fr.position, direct.position)
        np.testing.assert_array_equal(fr.normal, direct.normal)
        np.testing.assert_array_equal(fr.range, direct.range_m.astype(np.float32))
        np.testing.assert_array_equal(fr.id, direct.body_id)
        np.testing.assert_array_equal(fr.dn, dn)
        assert fr.radiance.dtype == np.float32 and fr.dn.dtype == np.uint16
        assert fr.radiance.max() > 0 and 0 < fr.dn.max() < 2 ** opts.bits
        # TruthSet.load is a faithful view of the EXR's channels
        ch = read_exr(ts.path / fr.meta["exr"])
        assert set(ch) == {"Y", *AOV_CHANNELS}
        np.testing.assert_array_equal(ch["Y"], fr.radiance)
        np.testing.assert_array_equal(np.stack([ch["P.X"], ch["P.Y"], ch["P.Z"]], -1), fr.position)

        # metadata: what the scenario says
        meta = fr.meta
        assert fr.index == k and fr.time_s == pytest.approx(k * sc.trajectory.dt_s)
        assert meta["exr"] == f"frames/{k:06d}.exr" and meta["dn"] == f"frames/{k:06d}.png"
        cam = meta["camera"]
        assert (cam["width"], cam["height"], cam["fx"], cam["fy"], cam["cx"], cam["cy"]) == (24, 18, 26.0, 25.0,
                                                                                              11.5, 8.5)
        assert cam["model"] == "pinhole" and cam["skew"] == 0.0
        assert cam == spec.camera.to_dict()
        assert meta["pose"]["position_m"] == [float(v) for v in spec.pose.position_m]
        s = np.asarray(sc.sun.direction, float)
        np.testing.assert_allclose(meta["sun"]["direction_render"], s / np.linalg.norm(s), rtol=0, atol=1e-15)
        assert meta["sun"]["irradiance_w_m2"] == sc.sun.irradiance_w_m2
        assert meta["sensor"]["exposure_s"] == float(opts.exposure_s)
        assert set(meta["bodies"]) == {b.name for b in sc.world.bodies}
        assert meta["bodies"]["sphere"]["radius_m"] == 1.0

        # geometry: P re-projects onto its pixel centre through the manifest's camera and pose;
        # range is the distance from the manifest's camera position
        R = rotation_from_quat_xyzw(meta["pose"]["quat_render_from_cam_xyzw"])
        pos = np.asarray(meta["pose"]["position_m"])
        hit = np.isfinite(fr.position).all(-1)
        assert hit.sum() > hit.size // 2
        assert np.all((fr.id >= 0) == hit)
        p_cam = R.inv().apply(fr.position[hit].astype(np.float64) - pos)
        sl = CameraModel.from_dict(cam).project(p_cam)
        ll, ss = np.nonzero(hit)
        np.testing.assert_allclose(sl, np.stack([ss, ll], -1), atol=2e-3)
        np.testing.assert_allclose(fr.range[hit], np.linalg.norm(fr.position[hit] - pos, axis=-1), rtol=1e-5)


# -------------------------------------------------------------------------- (d) scalar fallback
def test_scalar_fallback_when_llvm_is_missing(tmp_path):
    """DRJIT_LIBLLVM_PATH → a missing file: Dr.Jit cannot start its LLVM backend, so init_mitsuba falls
    back to scalar_rgb with a RuntimeWarning; the render still succeeds and agrees with LLVM."""
    from renderlab.files.truthset import TruthSet

    centre = ["--set", "render.pixel_filter=center", "--seed", "5"]
    env = {**os.environ, "DRJIT_LIBLLVM_PATH": "/nonexistent/libLLVM.so"}
    fb = tmp_path / "fallback"
    proc = subprocess.run([str(RENDERLAB), "render", str(SCENE), "--out", str(fb), *TINY, *centre],
                          capture_output=True, text=True, timeout=300, env=env)
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr
    assert "RuntimeWarning" in proc.stderr and "falling back to scalar_rgb" in proc.stderr, proc.stderr
    assert "llvm_ad_mono" in proc.stderr
    mf = _manifest(fb)
    assert mf["renderer"]["variant"] == "scalar_rgb"
    assert mf["scenario"]["render"]["variant"] == "llvm_ad_mono"  # what was asked for, kept

    ll = _render(tmp_path / "llvm", *centre)
    assert _manifest(ll)["renderer"]["variant"] == "llvm_ad_mono"
    a, b = TruthSet.open(fb), TruthSet.open(ll)
    for k in range(N_FRAMES):
        fs, fl = a.load(k), b.load(k)
        assert fs.rgb is None and fs.radiance is not None  # the mono scenario stays mono (Y) on fallback
        lit = fl.radiance > 1e-3 * fl.radiance.max()
        assert lit.sum() > lit.size // 3
        np.testing.assert_allclose(fs.radiance[lit], fl.radiance[lit], rtol=1e-4)
        np.testing.assert_allclose(fs.radiance[~lit], fl.radiance[~lit], rtol=0, atol=1e-3 * fl.radiance.max())
        np.testing.assert_array_equal(fs.id, fl.id)
        np.testing.assert_allclose(fs.position, fl.position, rtol=0, atol=1e-4)  # NaN where both miss
