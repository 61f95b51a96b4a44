"""Primary rays generated in the Dr.Jit kernel (:mod:`renderlab.render.mitsuba_rays`) against float64 oracles.

* Every camera model (pinhole, skewed K, Brown, Owen, OpenCV, Kannala–Brandt): the kernel's ray through
  each sample, projected back through :meth:`CameraModel.project` (float64), lands on the sample's pixel
  position (pinhole ≤ 1e-3 px — float32 only; distortion ≤ 0.01 px); pixel-centre rays ≤ 1e-3 px for every
  model; the pinhole rays also vs rays built from K directly (``tests/oracles.py``), and origins/extents on
  the near and far clip planes.
* Sub-pixel positions: the numpy formula frac(½ + j·α + u_pix) − ½ (the former path's); per sample index
  they are uniform over the pixel (Kolmogorov–Smirnov), so the box filter is unbiased — and over 48 seeds
  the mean radiance of edge pixels matches the float64 ray oracle's box-filtered value.
* The Dr.Jit path renders the numpy path's image (same sub-pixel positions and seeds): pinhole to float32
  rounding, truth AOVs equal; several passes of whole spp give the one-pass image; a CUDA variant request
  without a GPU falls back to LLVM through the same path.
"""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import REPO, scenario_dict
from oracles import camera_rays
from scipy import stats

from renderlab.geometry.camera import CameraModel
from renderlab.render.mitsuba_backend import subpixel_offsets
from renderlab.render.mitsuba_rays import pass_sizes

CAMERAS = {
    "pinhole": CameraModel(64, 48, 70.0, 64.0, 33.7, 21.2),
    "skewed-K": CameraModel(64, 48, 66.0, 71.0, 29.1, 26.4, skew=1.5, skew_yx=-0.8),
    "brown": CameraModel(64, 48, 68.0, 63.0, 34.2, 22.9, model="brown",
                         distortion={"k1": -0.21, "k2": 0.07, "k3": -0.01, "p1": 1.5e-3, "p2": -8e-4}),
    "owen": CameraModel(64, 48, 69.0, 65.0, 30.6, 24.1, model="owen",
                        distortion={"e1": 2e-4, "e2": -0.15, "e3": 1e-3, "e4": 0.02, "e5": 1e-3, "e6": -2e-3}),
    "opencv": CameraModel(64, 48, 68.0, 63.0, 34.2, 22.9, model="opencv",
                          distortion={"k1": -0.2, "k2": 0.05, "p1": 1e-3, "p2": -5e-4, "k4": 0.01, "s1": 1e-3,
                                      "tau_x": 0.01}),
    "kannala_brandt": CameraModel(64, 48, 30.0, 29.0, 31.5, 23.5, model="kannala_brandt",
                                  distortion={"k1": 0.02, "k2": -0.003}),
}
SPP = 8


@pytest.fixture(scope="module")
def mi():
    from renderlab.render.variant import init_mitsuba

    return init_mitsuba("llvm_ad_mono")


def _kernel_rays(mi, cam, R, o, near, far, shift):
    """(origins, directions, maxt, offsets) of all W·H·SPP samples (pixel-major) and of the pixel centres."""
    import drjit as dr

    from renderlab.render.mitsuba_rays import CameraRays, FramePose, aligned_f32

    cr = CameraRays(mi, dr, cam)
    pose = FramePose(mi, dr, R, o, near, far)
    n = cam.width * cam.height
    idx = dr.arange(mi.UInt32, n * SPP)
    pix = idx // SPP
    off = cr.offsets(pix, idx - pix * SPP, mi.Float(aligned_f32(shift)))
    ray = cr.world_rays(cr.sample_directions(pix, off), pose)
    centre = cr.world_rays(cr.centre_directions(dr.arange(mi.UInt32, n)), pose)
    arr = lambda v: np.array(v, dtype=np.float64).T  # noqa: E731
    return (arr(ray.o), arr(ray.d), np.array(ray.maxt, np.float64), arr(off)), (arr(centre.o), arr(centre.d))


@pytest.mark.parametrize("name", list(CAMERAS))
def test_kernel_rays_reproject_onto_their_samples(mi, name):
    """Kernel rays → CameraModel.project (float64) vs the sample positions; centres; clip planes."""
    from renderlab.dynamics.camera_paths import CameraPose
    from renderlab.geometry.rotations import look_at

    cam = CAMERAS[name]
    W, H = cam.width, cam.height
    rng = np.random.default_rng(3)
    shift = rng.random((W * H, 2))
    o = np.array([3.0, -2.0, 5.0])
    pose = CameraPose(time_s=0.0, position_m=o, rotation=look_at(o, np.zeros(3), [0, 0, 1]))
    R = pose.rotation.as_matrix()
    (org, d, maxt, off), (c_org, c_d) = _kernel_rays(mi, cam, R, o, 0.05, 500.0, shift)
    grid = cam.pixel_grid().reshape(-1, 2)
    expect_off = subpixel_offsets(SPP, W * H, np.random.default_rng(3)).transpose(1, 0, 2).reshape(-1, 2)
    assert np.abs(off - expect_off).max() < 1e-5, "sub-pixel offsets differ from the numpy formula"
    sl = np.repeat(grid, SPP, axis=0) + off  # the kernel's own positions
    d_cam = d @ R
    ok = np.isfinite(cam.unproject(sl)).all(axis=1)
    assert ok.mean() > 0.95
    err = np.linalg.norm(cam.project(d_cam[ok]) - sl[ok], axis=1)
    c_err = np.linalg.norm(cam.project(c_d @ R) - grid, axis=1)
    print(f"{name}: sample rays max {err.max():.2e} px (median {np.median(err):.1e}), centre rays max "
          f"{np.nanmax(c_err):.2e} px")
    limit = 1e-3 if cam.model == "pinhole" else 0.01
    assert err.max() <= limit, f"{name}: ray direction {err.max():.2e} px off the float64 oracle"
    assert np.nanmax(c_err) <= 1e-3
    if cam.model == "pinhole":  # independent of CameraModel.unproject: rays built from K
        _, d_k = camera_rays(SimpleNamespace(camera=cam, pose=pose), sl)
        ang = np.arccos(np.clip(np.einsum("ij,ij->i", d_k, d / np.linalg.norm(d, axis=1, keepdims=True)), -1, 1))
        assert (ang * max(cam.fx, cam.fy)).max() <= 1e-3
    depth0 = (org[ok] - o) @ R[:, 2]
    depth1 = (org[ok] + maxt[ok, None] * d[ok] - o) @ R[:, 2]
    assert np.allclose(depth0, 0.05, rtol=1e-4) and np.allclose(depth1, 500.0, rtol=1e-4)


def test_subpixel_offsets_are_uniform_per_sample_index():
    """Each sample index j is uniform over the pixel square (Cranley–Patterson rotation): KS test per axis."""
    off = subpixel_offsets(SPP, 4000, np.random.default_rng(11))
    p = [stats.kstest(off[j, :, a] + 0.5, "uniform").pvalue for j in range(SPP) for a in range(2)]
    assert min(p) > 1e-3, p
    assert np.all(off >= -0.5) and np.all(off < 0.5)


def test_pass_sizes_cover_spp_in_whole_passes():
    assert pass_sizes(16, 1000, limit=1 << 24) == [16]
    assert pass_sizes(16, 1000, limit=5000) == [5, 5, 5, 1]
    assert pass_sizes(3, 10**7, limit=100) == [1, 1, 1]


def _backend(camera=None, spp=16, variant="llvm_ad_mono"):
    from renderlab.pipeline import frame_specs, make_backend
    from renderlab.scenario import scenario_from_dict
    from renderlab.worlds.analytic import build_scene

    d = scenario_dict(render={"pixel_filter": "box", "spp": spp, "variant": variant})
    if camera is not None:
        d["camera"] = camera
    sc = scenario_from_dict(d)
    scene = build_scene(sc.world, REPO / "scenes")
    return make_backend(sc, scene, "mitsuba"), frame_specs(sc)[0], scene


def test_drjit_path_renders_the_numpy_path_image():
    """Same sub-pixel positions and seeds: the images agree to float32 rounding, the truth AOVs exactly;
    passes of whole spp (forced small) give the one-pass image."""
    be, spec, _ = _backend()
    be.ray_path = "numpy"
    a = be.render(spec, seed=4)
    be.ray_path = "drjit"
    b = be.render(spec, seed=4)
    assert np.abs(a.radiance - b.radiance).max() <= 1e-4 * a.radiance.max()
    assert np.array_equal(a.body_id, b.body_id)
    hit = a.body_id >= 0
    assert np.abs(a.position[hit] - b.position[hit]).max() < 1e-4
    assert np.allclose(a.range_m[hit], b.range_m[hit], rtol=1e-6)
    be.samples_per_pass = 64 * 48 * 5  # 16 spp as 5 + 5 + 5 + 1
    c = be.render(spec, seed=4)
    assert np.abs(c.radiance - b.radiance).max() <= 1e-5 * b.radiance.max()
    other = be.render(spec, seed=5)
    assert np.abs(other.radiance - c.radiance).max() > 1e-3 * c.radiance.max()  # the seed moves the samples


def test_box_filter_mean_matches_float64_oracle_on_silhouettes():
    """Mean over 48 seeds × 16 spp (768 samples) of the silhouette/shadow pixels vs the ray oracle's
    box-filtered radiance (32×32 stratified sub-samples), within the oracle's sampling tolerance
    (:func:`~renderlab.render.ray_oracle.consistent`). Up to 3 % of the edge pixels may fail: a shadow sliver
    narrower than 1/32 px between the oracle's sub-samples (one of 128 pixels here; with 16×16, three).
    The same pixels against the pattern shifted by half a pixel fail by the dozen."""
    from renderlab.render.ray_oracle import consistent, oracle_scene, pixel_truth

    cam = {"width": 32, "height": 24, "fx": 35.0, "fy": 32.0, "cx": 16.7, "cy": 10.6}
    be, spec, scene = _backend(camera=cam)
    mean = np.mean([be.render(spec, seed=s).radiance for s in range(48)], axis=0)
    one = be.render(spec, seed=100)
    from scipy import ndimage

    ids = one.body_id
    edge = (ndimage.maximum_filter(ids, 3) != ndimage.minimum_filter(ids, 3))
    ll, ss = np.nonzero(edge)
    sl = np.column_stack([ss, ll]).astype(float)
    truth = pixel_truth(oracle_scene(scene), spec, sl, k=32)
    ok = consistent(mean[ll, ss], truth, spp=768, k=32)
    worst = np.abs(mean[ll, ss] - truth.radiance).max()
    print(f"box filter on {len(sl)} edge px: {ok.mean():.1%} consistent, max |diff| {worst:.3f} W m^-2 sr^-1")
    assert len(sl) > 40 and ok.mean() >= 0.97
    # a half-pixel shift of the pattern (the usual off-by-half bug) would fail the same check
    spec_shift = replace(spec, camera=CameraModel(32, 24, 35.0, 32.0, 17.2, 11.1))
    moved = pixel_truth(oracle_scene(scene), spec_shift, sl, k=32)
    assert consistent(mean[ll, ss], moved, spp=768, k=32).mean() < 0.8


def test_cuda_request_without_gpu_takes_the_same_path():
    """cuda_ad_mono without a GPU falls back (warning) to llvm_ad_mono and renders the same Dr.Jit-path image."""
    import warnings

    import mitsuba

    be, spec, _ = _backend()
    ref = be.render(spec, seed=2)
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        cu, spec_cu, _ = _backend(variant="cuda_ad_mono")
    if cu.variant.startswith("cuda"):
        pytest.skip("a CUDA GPU is present: benchmarks/gpu_check.sh compares the images")
    assert cu.variant == "llvm_ad_mono" and not cu.scalar and cu.ray_path == "drjit"
    assert np.array_equal(cu.render(spec_cu, seed=2).radiance, ref.radiance)
    assert mitsuba.variant() == "llvm_ad_mono"


def test_device_variant_sends_llvm_requests_to_cuda():
    """RENDERLAB_MITSUBA_DEVICE (benchmarks/gpu_check.sh): cuda maps llvm_ad_<colour> → cuda_ad_<colour>."""
    from renderlab.errors import UserError
    from renderlab.render.variant import device_variant

    assert device_variant("llvm_ad_mono", "cuda") == "cuda_ad_mono"
    assert device_variant("llvm_ad_rgb", "cuda") == "cuda_ad_rgb"
    assert device_variant("cuda_ad_rgb", "llvm") == "llvm_ad_rgb"
    assert device_variant("scalar_rgb", "cuda") == "scalar_rgb"
    assert device_variant("llvm_ad_mono", "") == "llvm_ad_mono"
    with pytest.raises(UserError, match="RENDERLAB_MITSUBA_DEVICE"):
        device_variant("llvm_ad_mono", "gpu")


def test_drjit_grid_path_renders_the_kernel_path_image():
    """``ray_path = "drjit_grid"`` (pinholes through the float64 grid, the path before the kernel inverse) gives
    the kernel path's image to float32 rounding and the same truth AOVs; ``$RENDERLAB_MITSUBA_RAYS`` sets the
    default, and an unknown value is a one-line error."""
    import os
    import subprocess
    import sys

    from renderlab.errors import UserError

    be, spec, _ = _backend()
    a = be.render(spec, seed=4)
    be.ray_path = "drjit_grid"
    b = be.render(spec, seed=4)
    assert be._cam_rays.use_grid and not be._cam_rays.plane
    assert np.abs(a.radiance - b.radiance).max() <= 1e-4 * a.radiance.max()
    assert np.array_equal(a.body_id, b.body_id)
    be.ray_path = "drjit"
    c = be.render(spec, seed=4)
    assert not be._cam_rays.use_grid and np.array_equal(a.radiance, c.radiance)
    be.ray_path = "kernel"
    with pytest.raises(UserError, match="must be one of drjit, drjit_grid, numpy"):
        be.render(spec, seed=4)
    code = "from renderlab.render.mitsuba_backend import MitsubaBackend as M; print(M.ray_path)"
    out = subprocess.run([sys.executable, "-c", code], env={**os.environ, "RENDERLAB_MITSUBA_RAYS": "drjit_grid"},
                         capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "drjit_grid"


def test_bad_ray_path_from_the_environment_is_one_line_and_writes_nothing(tmp_path):
    """``$RENDERLAB_MITSUBA_RAYS`` with an unknown value: exit 2, one line naming it, no output folder."""
    import os
    import subprocess
    import sys

    scene = REPO / "scenes" / "analytic_sphere_box.toml"
    out = subprocess.run([sys.executable, "-m", "renderlab.cli", "render", str(scene), "--out", str(tmp_path / "o"),
                          "--quiet", "--set", "camera.width=40", "--set", "camera.height=30", "--set", "render.spp=1",
                          "--set", "trajectory.frames=1"],
                         env={**os.environ, "RENDERLAB_MITSUBA_RAYS": "kernel"}, capture_output=True, text=True)
    assert out.returncode == 2, out.stderr
    assert out.stderr.strip().splitlines() == [
        "renderlab: error: Mitsuba ray path (RENDERLAB_MITSUBA_RAYS) must be one of drjit, drjit_grid, numpy, "
        "got 'kernel'"], out.stderr
    assert list(tmp_path.iterdir()) == []
