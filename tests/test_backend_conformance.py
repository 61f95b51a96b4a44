"""Renderer backends (:data:`renderlab.plugins.renderers`: Mitsuba, Cycles, any installed one) against the same
independent oracles, on tiny scenes.

For every registered backend:

* camera convention: the position AOV at hit pixels re-projects through the frame's :class:`CameraModel` onto
  the pixel centre (≤ 0.01 px), for a pinhole, a skewed K, Brown and Owen cameras (Brown also through OpenCV);
  a backend that supports pinhole cameras only (Cycles) raises its one-line UserError instead;
* body ids (pixels away from silhouettes) and range agree with the float64 ray caster
  :mod:`renderlab.render.ray_oracle`; the range along the backend's own ray through P (immune to Cycles'
  ±0.005 px centre jitter);
* Lambert: L = A·E·cos(i)/π on a plane and a sphere (interior pixels, ≤ 1e-3 relative; centre sampling, and
  the box filter on the plane), each photometric law vs the numpy law, and Hapke under a nadir camera;
* the hard shadow edge of a box on a plane within 0.5 px of the analytic one (16×16 sub-samples, slab test);
* the same seed gives byte-identical truth sets; another seed changes the box-filtered pixels.

One backend instance per scene and settings for the whole module (Cycles: one worker subprocess each, fed
several frames).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from conftest import REPO, scenario_dict
from oracles import camera_rays, hit_box, hit_plane_z0, hit_sphere
from renderer_params import RENDERERS
from scipy import ndimage

from renderlab.errors import UserError
from renderlab.photometry import make_law

E_SUN = 1361.0
LAWS = ["lambert", "lommel_seeliger", "mcewen", "hapke"]
SPHERE_C = np.array([-0.5, 0.4, 1.0])  # conftest's BASE_SCENARIO sphere (radius 1) over a 20 m plane
PINHOLE_ONLY = {"cycles"}  # backends whose camera is a pinhole only (skew and distortion: UserError)
CAMERAS = {
    "pinhole": {"fx": 70.0, "fy": 64.0, "cx": 33.7, "cy": 21.2},
    "skewed-K": {"fx": 66.0, "fy": 71.0, "cx": 29.1, "cy": 26.4, "skew": 1.5, "skew_yx": -0.8},
    "brown": {"fx": 68.0, "fy": 63.0, "cx": 34.2, "cy": 22.9, "model": "brown",
              "distortion": {"k1": -0.21, "k2": 0.07, "k3": -0.01, "p1": 1.5e-3, "p2": -8e-4}},
    "owen": {"fx": 69.0, "fy": 65.0, "cx": 30.6, "cy": 24.1, "model": "owen",
             "distortion": {"e1": 2e-4, "e2": -0.15, "e3": 1e-3, "e4": 0.02, "e5": 1e-3, "e6": -2e-3}},
}
BOX_BODIES = [
    {"name": "ground", "shape": "plane", "center_m": [0, 0, 0], "size_m": [20, 20], "law": "lambert", "albedo": 0.3},
    {"name": "box", "shape": "box", "center_m": [0, 0, 0.6], "size_m": [1.2, 1.2, 1.2], "law": "lambert", "albedo": 0.3}]




def _scenes() -> dict[str, dict]:
    """Scenario dicts of the module's scenes, by key."""
    sun = np.array([0.45, 0.25, 0.6])
    nadir_sun = np.array([0.45, 0.2, 0.8])
    law_bodies = [{"name": law, "shape": "sphere", "center_m": [1.3 * (2 * (k % 2) - 1), 1.3 * (2 * (k // 2) - 1), 0.0],
                   "radius_m": 1.0, "law": law, "albedo": 0.08 if law == "hapke" else 0.4} for k, law in enumerate(LAWS)]
    centre = {"pixel_filter": "center", "spp": 1}
    return {
        "base_centre": scenario_dict(render=centre),
        "base_box": scenario_dict(render={"pixel_filter": "box", "spp": 16}),
        "laws": scenario_dict(world={"kind": "analytic", "bodies": law_bodies}, render=centre,
                              camera={"width": 96, "height": 80, "fx": 150.0, "fy": 146.0, "cx": 47.6, "cy": 39.3}),
        "hapke_nadir": scenario_dict(
            world={"kind": "analytic", "bodies": [{"name": "ground", "shape": "plane", "center_m": [0, 0, 0],
                                                   "size_m": [40, 40], "law": "hapke", "albedo": 0.085}]},
            sun={"direction": (nadir_sun / np.linalg.norm(nadir_sun)).tolist()}, render=centre,
            camera={"width": 96, "height": 80, "fx": 60.0, "fy": 58.0, "cx": 47.6, "cy": 39.3},
            trajectory={"kind": "line", "frames": 1, "start_m": [0.0, 0.0, 5.0], "target_m": [0.0, 0.0, 0.0],
                        "up": [0, 1, 0]}),
        "shadow": scenario_dict(
            world={"kind": "analytic", "bodies": BOX_BODIES}, sun={"direction": (sun / np.linalg.norm(sun)).tolist()},
            camera={"width": 80, "height": 60, "fx": 60.0, "fy": 57.0, "cx": 40.3, "cy": 29.6},
            trajectory={"kind": "line", "frames": 1, "start_m": [0.3, 0.2, 8.0], "target_m": [-0.6, -0.4, 0.0],
                        "up": [0, 1, 0]},
            render={"pixel_filter": "box", "spp": 64}),
    }


@pytest.fixture(scope="module")
def backends():
    """``get(renderer, scene_key) -> (backend, specs, scene)``: one backend per pair, closed at module end."""
    from renderlab.pipeline import frame_specs, make_backend
    from renderlab.scenario import scenario_from_dict
    from renderlab.worlds.analytic import build_scene

    cache, scenes = {}, _scenes()

    def get(renderer: str, key: str):
        if (renderer, key) not in cache:
            sc = scenario_from_dict(scenes[key])
            scene = build_scene(sc.world, REPO / "scenes")
            cache[renderer, key] = (make_backend(sc, scene, renderer), frame_specs(sc), scene)
        return cache[renderer, key]

    yield get
    for backend, _, _ in cache.values():
        if hasattr(backend, "close"):
            backend.close()


def _pixel_sl(shape):
    H, W = shape
    ll, ss = np.mgrid[0:H, 0:W]
    return np.column_stack([ss.ravel(), ll.ravel()]).astype(float)


def _interior(ids, lit):
    """Pixels whose 3×3 neighbourhood has one id and is lit (not on the image border)."""
    one = ndimage.minimum_filter(ids, 3) == ndimage.maximum_filter(ids, 3)
    one[[0, -1], :] = False
    one[:, [0, -1]] = False
    return one & (ndimage.minimum_filter(lit.astype(np.uint8), 3) > 0)


def _oracle_hits(oracle, o, d):
    """Float64 first hits of rays (ray_oracle): distance (inf: miss) and body id (−1: miss)."""
    from renderlab.render.ray_oracle import _first_hit

    t, prim, _, _ = _first_hit(oracle, np.ascontiguousarray(o, float), np.ascontiguousarray(d, float),
                               np.arange(len(oracle.tri)), 0.0)
    body = np.full(len(t), -1)
    tri = np.isfinite(t) & (prim >= 0)
    body[tri] = oracle.tri_body[prim[tri]]
    for k, (_, _, b) in enumerate(oracle.spheres):
        body[np.isfinite(t) & (prim == -1 - k)] = b
    ids = np.array([b.body_id for b in oracle.bodies] + [-1])[body]
    return t, ids


@pytest.mark.parametrize("renderer", RENDERERS)
@pytest.mark.parametrize("camera", list(CAMERAS))
def test_camera_convention_ids_and_range(renderer, camera, backends):
    """Position AOV → pixel centre ≤ 0.01 px through the frame's camera; ids and range vs the ray oracle."""
    import cv2

    from renderlab.pipeline import frame_specs
    from renderlab.render.ray_oracle import oracle_scene
    from renderlab.scenario import scenario_from_dict

    backend, _, scene = backends(renderer, "base_centre")
    spec = frame_specs(scenario_from_dict(scenario_dict(camera=CAMERAS[camera], render={"pixel_filter": "center"})))[0]
    if camera != "pinhole" and renderer in PINHOLE_ONLY:
        with pytest.raises(UserError, match="pinhole cameras only") as ei:
            backend.render(spec, seed=1)
        assert "\n" not in str(ei.value)
        return
    out = backend.render(spec, seed=1)
    cam, R, c0 = spec.camera, spec.pose.rotation.as_matrix(), np.asarray(spec.pose.position_m, float)
    sl = _pixel_sl(out.body_id.shape)
    hit = (out.body_id >= 0).ravel()
    P = out.position.reshape(-1, 3)[hit].astype(np.float64)
    err = np.linalg.norm(cam.project((P - c0) @ R) - sl[hit], axis=1)
    assert hit.sum() > 1000 and err.max() <= 0.01, f"position AOV re-projects {err.max():.4f} px off the centre"
    if camera == "brown":  # independent projection with OpenCV
        dist = cam.distortion
        K = np.array([[cam.fx, cam.skew, cam.cx], [0, cam.fy, cam.cy], [0, 0, 1.0]])
        sl_cv, _ = cv2.projectPoints((P - c0) @ R, np.zeros(3), np.zeros(3), K,
                                     np.array([dist["k1"], dist["k2"], dist["p1"], dist["p2"], dist["k3"]]))
        assert np.abs(sl_cv[:, 0, :] - sl[hit]).max() <= 0.01
    oracle = oracle_scene(scene)
    d = cam.unproject(sl) @ R.T
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    t, ids = _oracle_hits(oracle, np.broadcast_to(c0, d.shape), d)
    ids = ids.reshape(out.body_id.shape)
    inner = _interior(ids, np.ones(ids.shape, bool))
    assert inner.sum() > 0.8 * ids.size and np.array_equal(out.body_id[inner], ids[inner])
    assert np.all(np.isnan(out.position[out.body_id == -1]))
    # range: ‖P − camera‖, and the oracle's first hit along the backend's own ray through P
    rng = out.range_m.ravel()[hit]
    assert np.allclose(rng, np.linalg.norm(P - c0, axis=1), rtol=1e-6)
    same = inner.ravel()[hit]
    u = (P - c0)[same] / rng[same, None]
    t_own, _ = _oracle_hits(oracle, np.broadcast_to(c0, u.shape), u)
    rel = np.abs(rng[same] / t_own - 1)
    assert rel.max() <= 1e-5, f"range differs from the oracle's by {rel.max():.2e} (relative)"
    # over all pixels (silhouettes too) the ids tell conventions apart: pixel corners at integers would move
    # the sphere's outline by half a pixel
    _, shifted = _oracle_hits(oracle, np.broadcast_to(c0, d.shape), _unit(cam.unproject(sl + 0.5) @ R.T))
    off, off_shifted = (ids != out.body_id).sum(), (shifted.reshape(ids.shape) != out.body_id).sum()
    print(f"{renderer}/{camera}: reprojection max {err.max():.2e} px, range rel max {rel.max():.2e}, "
          f"ids off {off} (shifted convention: {off_shifted})")
    assert off <= 5 and off_shifted > off + 20


def _unit(v):
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _lambert_expected(spec, shape):
    """Centre-ray Lambert radiance of the base scene (analytic sphere/plane, sphere's cast shadow) and ids."""
    sun = _unit(np.array([[0.5, -0.3, 0.8]]))[0]
    o, d = camera_rays(spec, _pixel_sl(shape))
    t_s, t_p = hit_sphere(o, d, SPHERE_C, 1.0), hit_plane_z0(o, d, (10, 10))
    t = np.minimum(t_s, t_p)
    on_sphere = t_s < t_p
    p = o + np.where(np.isfinite(t), t, 0.0)[:, None] * d
    n = _unit(np.where(on_sphere[:, None], p - SPHERE_C, [0.0, 0.0, 1.0]))
    shadowed = np.isfinite(hit_sphere(p + 1e-6 * n, np.broadcast_to(sun, p.shape), SPHERE_C, 1.0)) & ~on_sphere
    expect = np.where(on_sphere, 0.5, 0.25) * E_SUN * np.clip(n @ sun, 0, None) / np.pi * ~shadowed
    ids = np.where(np.isfinite(t), on_sphere.astype(int), -1)
    return expect.reshape(shape), ids.reshape(shape)


@pytest.mark.parametrize("renderer", RENDERERS)
@pytest.mark.parametrize("pixel_filter", ["center", "box"])
def test_lambert_sphere_and_plane_match_closed_form(renderer, pixel_filter, backends):
    """L = A·E·cos(i)/π, cos(i) from the analytic normal, the sphere's shadow by analytic ray casting
    (box filter: on the plane only, where L is constant over a pixel)."""
    backend, specs, _ = backends(renderer, "base_centre" if pixel_filter == "center" else "base_box")
    out = backend.render(specs[0], seed=3)
    expect, ids = _lambert_expected(specs[0], out.body_id.shape)
    mask = _interior(ids, expect > 0.05 * expect.max()) & (ids >= 0)
    if pixel_filter == "box":
        mask &= ids == 0
    assert mask.sum() > 300
    rel = np.abs(out.radiance[mask] / expect[mask] - 1)
    print(f"{renderer}/{pixel_filter}: Lambert max relative error {rel.max():.2e} over {mask.sum()} px")
    assert rel.max() <= 1e-3, f"max relative error {rel.max():.2e} over {mask.sum()} pixels"
    if pixel_filter == "center":
        assert np.all(out.radiance[ids == -1] == 0)


def _law_geometries(n=3):
    rng = np.random.default_rng(4)
    out = []
    for _ in range(n):
        az, el = rng.uniform(-np.pi, np.pi), rng.uniform(0.5, 1.3)
        to_cam = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
        sun = _unit(rng.normal(size=(1, 3)))[0]
        if sun @ to_cam < -0.2:  # keep the phase angle below ~100° so that enough of each disc is lit
            sun = _unit((sun - 1.2 * (sun @ to_cam) * to_cam)[None])[0]
        out.append((to_cam, sun))
    return out


@pytest.mark.parametrize("renderer", RENDERERS)
def test_each_law_matches_numpy_reference(renderer, backends):
    """Four spheres, one per law, three random sun/camera geometries (frames of one backend): radiance vs the
    numpy law at the analytic hit point and normal of each pixel centre (interior pixels, ≤ 1e-3)."""
    from renderlab.dynamics.camera_paths import CameraPose
    from renderlab.geometry.rotations import look_at
    from renderlab.render.scene import SunSpec

    backend, specs, scene = backends(renderer, "laws")
    centres = np.array([b.center_m for b in scene.bodies], float)
    albedo = {b.name: float(b.albedo) for b in scene.bodies}
    checked, worst = set(), {}
    for to_cam, sun in _law_geometries():
        pos = 14 * to_cam
        spec = replace(specs[0], pose=CameraPose(time_s=0.0, position_m=pos, rotation=look_at(pos, np.zeros(3), [0, 0, 1])),
                       sun=SunSpec(direction_render=sun, irradiance_w_m2=E_SUN))
        out = backend.render(spec, seed=2)
        o, dirs = camera_rays(spec, _pixel_sl(out.body_id.shape))
        ts = np.stack([hit_sphere(o, dirs, c, 1.0) for c in centres])
        which, t = np.argmin(ts, axis=0), ts.min(axis=0)
        ids = np.where(np.isfinite(t), which, -1).reshape(out.body_id.shape)
        n = _unit(o + np.where(np.isfinite(t), t, 0.0)[:, None] * dirs - centres[which])
        mu0, mu, g = n @ sun, np.einsum("ij,ij->i", n, -dirs), np.arccos(np.clip(-dirs @ sun, -1, 1))
        for k, law in enumerate(LAWS):
            m = (_interior(ids, out.radiance > 0) & (ids == k)).ravel() & (mu0 > 0.1) & (mu > 0.1)
            if m.sum() < 20:  # this sphere is hidden or unlit in this geometry
                continue
            expect = E_SUN * make_law(law).radiance_factor(mu0[m], mu[m], g[m], albedo[law])
            rel = np.abs(out.radiance.ravel()[m] / expect - 1)
            worst[law] = max(worst.get(law, 0.0), rel.max())
            assert rel.max() <= 1e-3, f"{law}: max relative error {rel.max():.2e} over {m.sum()} px"
            checked.add(law)
    print(f"{renderer}: law max relative errors " + ", ".join(f"{k} {v:.1e}" for k, v in worst.items()))
    assert checked == set(LAWS)


@pytest.mark.parametrize("renderer", RENDERERS)
def test_hapke_viewed_along_the_normal(renderer, backends):
    """Rough Hapke plane under a nadir camera (emission 0.5-46°): every pixel matches the numpy law to 1e-3.
    Cycles' OSL shader once took the azimuth from (cos g − mu0·mu)/(sin i sin e), which loses all float32 digits
    as e → 0 (NaN radiance: black pixels)."""
    backend, specs, scene = backends(renderer, "hapke_nadir")
    out = backend.render(specs[0], seed=3)
    o, dirs = camera_rays(specs[0], _pixel_sl(out.radiance.shape))
    assert np.all(np.isfinite(hit_plane_z0(o, dirs)))
    sun, v = np.asarray(specs[0].sun.direction_render, float), -dirs
    assert v[:, 2].max() > 0.9999  # emission below 0.8° near the principal point
    expect = E_SUN * make_law("hapke").radiance_factor(np.full(len(v), sun[2]), v[:, 2], np.arccos(v @ sun), 0.085)
    rel = np.abs(out.radiance.ravel() / expect - 1)
    print(f"{renderer}: Hapke at nadir max relative error {rel.max():.2e}")
    assert rel.max() <= 1e-3, f"{int((rel > 1e-3).sum())} px off, {int((out.radiance == 0).sum())} black"


@pytest.mark.parametrize("renderer", RENDERERS)
def test_box_shadow_edge_on_plane_within_half_pixel(renderer, backends):
    """Box on a plane, 1-px box filter, 64 spp: the lit fraction of each plane pixel vs the analytic one
    (16×16 sub-samples, slab test toward the sun); edge displacement ≤ 0.5 px, median ≤ 0.1 px."""
    backend, specs, _ = backends(renderer, "shadow")
    spec = specs[0]
    out = backend.render(spec, seed=5)
    sun = np.asarray(spec.sun.direction_render, float)
    lo, hi = np.array([-0.6, -0.6, 0.0]), np.array([0.6, 0.6, 1.2])
    frac_r = out.radiance / (0.3 * E_SUN * sun[2] / np.pi)
    H, W = out.radiance.shape
    k = 16
    du, dv = np.meshgrid((np.arange(k) + 0.5) / k - 0.5, (np.arange(k) + 0.5) / k - 0.5)
    sl = (_pixel_sl((H, W))[:, None, :] + np.column_stack([du.ravel(), dv.ravel()])[None]).reshape(-1, 2)
    o, dd = camera_rays(spec, sl)
    t_p, t_b = hit_plane_z0(o, dd), hit_box(o, dd, lo, hi)
    p = o + t_p[:, None] * dd
    lit = ~np.isfinite(hit_box(p + [0, 0, 1e-7], np.broadcast_to(sun, p.shape), lo, hi))
    frac_o = lit.reshape(H, W, k * k).mean(axis=2)
    plane_px = ndimage.minimum_filter((t_p < t_b).reshape(H, W, k * k).all(axis=2).astype(np.uint8), 3) > 0
    gy, gx = np.gradient(frac_o)
    grad = np.hypot(gx, gy)
    edge = plane_px & (frac_o > 0.05) & (frac_o < 0.95) & (grad > 0.05)
    assert edge.sum() >= 10, "the test scene must put a shadow edge on the plane"
    disp = np.abs(frac_r[edge] - frac_o[edge]) / grad[edge]
    print(f"{renderer}: shadow edge displacement max {disp.max():.3f} px, median {np.median(disp):.3f} px "
          f"over {edge.sum()} edge px")
    assert disp.max() <= 0.5, f"shadow edge displaced by up to {disp.max():.3f} px"
    assert np.median(disp) <= 0.1
    full = lambda m: ndimage.minimum_filter(m.astype(np.uint8), 3) > 0  # noqa: E731
    inside = plane_px & (full(frac_o == 0) | full(frac_o == 1))  # fully lit or fully shadowed, with neighbours
    assert inside.sum() > 100
    assert np.abs(frac_r[inside] - frac_o[inside]).max() < 1e-3


@pytest.mark.parametrize("renderer", RENDERERS)
def test_same_seed_gives_identical_truth_set(renderer, tmp_path):
    """render_truthset twice with one seed: byte-identical EXR and PNG files; another seed changes the
    box-filtered edge pixels; the manifest names the renderer."""
    import json

    from renderlab.pipeline import render_truthset
    from renderlab.scenario import scenario_from_dict

    bodies = [dict(BOX_BODIES[0], albedo=0.25), dict(BOX_BODIES[1], law="hapke")]
    sc = scenario_from_dict(scenario_dict(world={"kind": "analytic", "bodies": bodies},
                                          camera={"width": 48, "height": 36, "fx": 52.0, "fy": 50.0, "cx": 23.6, "cy": 17.9},
                                          render={"spp": 4, "seed": 9, "renderer": renderer}))
    paths = [render_truthset(sc, REPO / "scenes", tmp_path / name, seed=seed, progress=False)
             for name, seed in (("a", 9), ("b", 9), ("c", 10))]
    for rel in ("frames/000000.exr", "frames/000000.png"):
        assert (paths[0] / rel).read_bytes() == (paths[1] / rel).read_bytes(), rel
    assert (paths[0] / "frames/000000.exr").read_bytes() != (paths[2] / "frames/000000.exr").read_bytes()
    assert json.loads((paths[0] / "manifest.json").read_text())["renderer"]["name"] == renderer
