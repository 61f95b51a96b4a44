"""Retina's fast synthetic image (z-buffer rasterisation + sun-aligned shadow sweep, ``tracer="raster"``)
against the reference ray caster (``tracer="numba"``, every shadow ray cast), and the fitted McEwen
weight L(α) against the lab's photometric laws (independent oracles: ``renderlab.photometry``).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.ndimage import binary_dilation, gaussian_filter

from estimators.onboard_photometry import beta_of_phase, fit_lunar_lambert_L, mcewen_relative
from estimators.retina import (
    CameraPoseEstimate,
    RetinaOptions,
    TemplateOptions,
    build_mesh,
    measure_landmark,
    render_template,
)
from estimators.retina.raster import shadow_gap_grid
from estimators.retina.raytrace import trace_rays
from renderlab.geometry.camera import CameraModel
from renderlab.geometry.maplet import Maplet

CAM = CameraModel.from_dict({"width": 160, "height": 160, "fx": 300.0, "fy": 300.0, "cx": 79.5, "cy": 79.5,
                             "skew": 0.3})
R_DOWN = np.diag([1.0, -1.0, -1.0])  # looking straight down the maplet's −z


def _terrain_maplet(n=49, spacing=0.05, seed=1):
    """Smooth relief with boulder-like bumps (long, narrow cast shadows) and an albedo texture."""
    rng = np.random.default_rng(seed)
    h = gaussian_filter(rng.normal(0, 0.08, (n, n)), 2.0)
    for _ in range(12):
        j, i = rng.integers(3, n - 3, 2)
        r = rng.uniform(1.0, 2.5)
        yy, xx = np.mgrid[:n, :n]
        h += rng.uniform(0.08, 0.25) * np.clip(1 - ((yy - j) ** 2 + (xx - i) ** 2) / r ** 2, 0, None) ** 0.5
    a = np.clip(1 + 0.3 * gaussian_filter(rng.normal(size=(n, n)), 1.5) / 0.2, 0.3, 3)
    return Maplet(7, np.array([0.1, -0.05, 0.0]), np.eye(3), spacing, h, a)


def _pose(offset=(0.0, 0.0)):
    return CameraPoseEstimate(R_DOWN @ _tilt(), np.array([0.3 + offset[0], -0.2 + offset[1], 9.0]))


def _tilt():
    from scipy.spatial.transform import Rotation

    return Rotation.from_rotvec([0.03, -0.02, 0.4]).as_matrix()


SUN = np.array([0.62, -0.35, 0.45]) / np.linalg.norm([0.62, -0.35, 0.45])  # ~33° elevation


@pytest.mark.parametrize("k", [1, 2])
def test_raster_template_equals_raycast_away_from_shadow_edges(k):
    mesh = build_mesh(_terrain_maplet())
    pose = _pose()
    ref = render_template(mesh, CAM, pose, SUN, TemplateOptions(supersample=k, tracer="numba"))
    fast = render_template(mesh, CAM, pose, SUN, TemplateOptions(supersample=k, tracer="raster"))
    lit = render_template(mesh, CAM, pose, SUN, TemplateOptions(supersample=k, tracer="numba", shadow_rays=False))
    assert (fast.s0, fast.l0, fast.image.shape) == (ref.s0, ref.l0, ref.image.shape)
    np.testing.assert_array_equal(fast.valid, ref.valid)
    v = ref.valid
    assert v.sum() > 2000 and ref.shadow_fraction > 0.03, (v.sum(), ref.shadow_fraction)
    # shadow edges of the reference: pixels next to both a pixel with a cast-shadowed sample and one
    # without, widened by 1 px (there a sub-pixel shadow may be missed or a sample flip side)
    shadowed = v & (lit.image - ref.image > 1e-12)
    boundary = binary_dilation(shadowed) & binary_dilation(~shadowed)
    inner = v & ~binary_dilation(boundary)
    d = np.abs(fast.image - ref.image)
    np.testing.assert_allclose(fast.image[inner], ref.image[inner], rtol=1e-9, atol=1e-12)
    assert (inner & shadowed).sum() > 5  # the comparison covers shadow interiors, not only lit ground
    assert inner.sum() > 0.5 * v.sum()
    # overall: the shadowed share of samples agrees to 5 % of itself; few pixels differ at all
    assert fast.shadow_fraction == pytest.approx(ref.shadow_fraction, rel=0.05)
    assert (d[v] > 1e-9).mean() < 0.05, (d[v] > 1e-9).mean()


def test_raster_and_raycast_measure_the_same_shift():
    """The same image, the same a-priori pose: the two templates' measured shifts differ by ≤ 0.01 px."""
    M = _terrain_maplet()
    mesh = build_mesh(M)
    true = _pose()
    tpl = render_template(mesh, CAM, true, SUN, TemplateOptions(supersample=3, tracer="numba"))
    img = np.full((CAM.height, CAM.width), 0.05)
    sl = np.s_[tpl.l0:tpl.l0 + tpl.image.shape[0], tpl.s0:tpl.s0 + tpl.image.shape[1]]
    img[sl] = np.where(tpl.valid, tpl.image, 0.05)
    for off in [(0.011, -0.017), (-0.023, 0.006)]:
        ap = _pose(off)
        out = []
        for tracer in ("numba", "raster"):
            opts = RetinaOptions(template=TemplateOptions(supersample=2, tracer=tracer), peak="upsampled")
            r = measure_landmark(img, mesh, CAM, ap, SUN, 4, opts)
            assert r.has_result, r.flags
            out.append((r.ds, r.dl))
        assert abs(out[0][0]) + abs(out[0][1]) > 0.3  # a real shift was measured
        assert np.hypot(out[0][0] - out[1][0], out[0][1] - out[1][1]) <= 0.01, out


def test_shadow_sweep_agrees_with_shadow_rays_at_its_grid_points():
    """G > 0 on the sun-aligned sweep grid vs the exact shadow ray cast from the same surface points."""
    mesh = build_mesh(_terrain_maplet())
    n, sp = mesh.n, mesh.spacing
    G, (dx, dy, r0, q0, step) = shadow_gap_grid(mesh.heights, sp, SUN, 0.5)
    r, q = np.nonzero(np.isfinite(G))
    pr, pq = (r - r0) * step, (q - q0) * step
    u, v = (n - 1) / 2 + pq * dx - pr * dy, (n - 1) / 2 + pq * dy + pr * dx
    inside = (u > 0.5) & (v > 0.5) & (u < n - 1.5) & (v < n - 1.5)
    # height on the maplet's own triangulation (cell (j, i) split along its (j, i)-(j+1, i+1) diagonal)
    H = mesh.heights
    i0, j0 = np.floor(u[inside]).astype(int), np.floor(v[inside]).astype(int)
    fu, fv = u[inside] - i0, v[inside] - j0
    z = np.where(fu >= fv,
                 H[j0, i0] + fu * (H[j0, i0 + 1] - H[j0, i0]) + fv * (H[j0 + 1, i0 + 1] - H[j0, i0 + 1]),
                 H[j0, i0] + fv * (H[j0 + 1, i0] - H[j0, i0]) + fu * (H[j0 + 1, i0 + 1] - H[j0 + 1, i0]))
    pts = np.column_stack([(u[inside] - (n - 1) / 2) * sp, (v[inside] - (n - 1) / 2) * sp, z])
    # a ray from just above the surface point straight toward the sun: any hit = in shadow
    hit, _, _, _ = trace_rays(pts + np.array([0, 0, 1e-7]), np.tile(SUN, (len(pts), 1)), mesh.heights,
                              mesh.cell_min, mesh.cell_max, sp, mesh.normals, np.zeros(3), 0.0)
    sweep = G[r, q][inside] > 1e-6
    assert 0.03 < hit.mean() < 0.5, hit.mean()  # the terrain casts shadows on a real share of points
    assert (sweep == hit).mean() > 0.98, (sweep == hit).mean()


@pytest.mark.parametrize("law, expect", [("mcewen", None), ("lambert", 0.0), ("lommel_seeliger", 1.0)])
def test_fitted_L_recovers_laws_of_lunar_lambert_form(law, expect):
    from renderlab.photometry import make_law

    L = make_law(law, **({"alpha0": math.radians(45.0)} if law == "mcewen" else {}))
    fit = fit_lunar_lambert_L(lambda mu0, mu, g: L.radiance_factor(mu0, mu, g, 0.2))
    ok = fit.phase_rad <= math.radians(140.0)  # beyond i_max + e_max − 10° too few geometries
    want = np.exp(-fit.phase_rad / math.radians(45.0)) if expect is None else np.full(len(fit.L), expect)
    np.testing.assert_allclose(fit.L[ok], want[ok], atol=1e-9)
    assert np.all(fit.rms_rel[ok] < 1e-9)


def test_fitted_L_describes_hapke_better_than_fixed_alpha0():
    """On the EV5 default Hapke law (Mathilde parameters, w = 0.085) the fitted L(α) leaves a smaller
    residual than Retina's exp(−α/60°), scoring both with the gain each fits best (eq. 9 is gain-free)."""
    from renderlab.photometry import make_law

    law = make_law("hapke")
    fit = fit_lunar_lambert_L(lambda mu0, mu, g: law.radiance_factor(mu0, mu, g, 0.085))
    rng = np.random.default_rng(0)
    for phase_deg in (20.0, 45.0, 70.0):
        g = math.radians(phase_deg)
        i, e = np.radians(rng.uniform(0, 80, 4000)), np.radians(rng.uniform(0, 70, 4000))
        ok = (np.abs(i - e) <= g) & (g <= i + e)
        mu0, mu = np.cos(i[ok]), np.cos(e[ok])
        r = law.radiance_factor(mu0, mu, np.full(mu0.shape, g), 0.085)

        def resid(L_table, mu0=mu0, mu=mu, g=g, r=r):
            m = mcewen_relative(mu0, mu, np.full(mu0.shape, g), 1.0, L_table=L_table)
            return np.sqrt(np.mean((r - m * (m @ r) / (m @ m)) ** 2)) / r.mean()

        fitted, fixed = resid(fit.L), resid(None)
        assert fitted < fixed, (phase_deg, fitted, fixed)
        assert beta_of_phase(g, L_table=fit.L) == pytest.approx(np.interp(g, fit.phase_rad, fit.L))


def test_L_table_reaches_the_kernels():
    """The numba ray caster, the raster path and the numpy pipeline all shade with the tabulated L(α)."""
    M = _terrain_maplet(n=17, spacing=0.1)
    mesh = build_mesh(M)
    pose = CameraPoseEstimate(R_DOWN, np.array([0.05, 0.02, 6.0]))
    table = tuple(np.linspace(0.9, 0.1, 181))
    imgs = {}
    for tracer in ("numba", "raster", "numpy"):
        imgs[tracer] = render_template(mesh, CAM, pose, np.array([0.0, 0.0, 1.0]),  # sun at zenith: no cast shadow
                                       TemplateOptions(supersample=2, tracer=tracer, L_table=table)).image
    plain = render_template(mesh, CAM, pose, np.array([0.0, 0.0, 1.0]), TemplateOptions(supersample=2)).image
    np.testing.assert_allclose(imgs["numba"], imgs["numpy"], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(imgs["raster"], imgs["numpy"], rtol=1e-9, atol=1e-12)
    assert np.abs(plain - imgs["numba"]).max() > 1e-3  # the table changed the image
