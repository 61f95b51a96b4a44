"""The closed gravity body of the EV5 world (:mod:`renderlab.worlds.ev5.gravity_mesh`) and a flight under its field.

Oracles not computed by the lab: trimesh's topology and mass properties (watertight, winding, volume, Euler number,
centre of mass, inertia tensor), Newton's GM/r² and MacCullagh's quadrupole formula far from the body, and Gauss's
∇²U = 0 outside / −4πGρ inside. The rendered global mesh is cut under the site, so it is the open one; the gravity
body is the same surface uncut (its vertices the rendered shape's before the cut, bit for bit). A closed-loop flight of
the study ``descent_gnc`` on the tiny world with ``gravity = "polyhedron"`` runs to contact on the site DEM.
"""

from __future__ import annotations

import tomllib

import numpy as np
import pytest
import trimesh
from tiny_ev5 import TINY_EV5_WORLD

GM = 2.9


@pytest.fixture(scope="module")
def world():
    from renderlab.worlds.ev5.config import EV5World

    return EV5World(**tomllib.loads(TINY_EV5_WORLD)["world"])


@pytest.fixture(scope="module")
def body(world):
    from renderlab.worlds.ev5.gravity_mesh import gravity_mesh

    return gravity_mesh(world)


def _topology(v, f):
    m = trimesh.Trimesh(v, f, process=False)
    return m, (m.is_watertight, m.is_winding_consistent, m.euler_number)


def test_gravity_body_is_the_rendered_surface_uncut_and_closed(world, body):
    from renderlab.worlds.ev5 import stream
    from renderlab.worlds.ev5.shape import procedural_shape
    from renderlab.worlds.ev5.site import build_site

    full = procedural_shape(world, stream(world.seed, "shape"))
    assert body.vertices.tobytes() == full.vertices.tobytes() and np.array_equal(body.faces, full.faces)
    m, topo = _topology(body.vertices, body.faces)
    assert topo == (True, True, 2) and m.volume > 0
    # the open mesh is the rendered one, cut under the site: its one-face edges ring the patch
    site, cut = build_site(full, world.site, world.facet_m, stream(world.seed, "terrain"),
                           stream(world.seed, "boulders"))
    mc, topo_cut = _topology(cut.vertices, cut.faces)
    assert topo_cut[0] is False and topo_cut[2] == 1
    edges, counts = np.unique(np.sort(mc.edges, axis=1), axis=0, return_counts=True)
    ring = (cut.vertices[np.unique(edges[counts == 1])] - site.origin_m) @ site.R_body_from_site
    assert len(ring) > 0 and np.abs(ring[:, :2]).max() < -site.x0_m and np.abs(ring[:, 2]).max() < 5.0
    # a coarser gravity body samples the same r(u): closed too, the same volume to the facet sampling
    from renderlab.worlds.ev5.gravity_mesh import gravity_mesh

    coarse = gravity_mesh(world, facet_m=16.0)
    mk, topo_k = _topology(coarse.vertices, coarse.faces)
    assert topo_k == (True, True, 2) and len(coarse.faces) < len(body.faces)
    np.testing.assert_allclose(np.linalg.norm(coarse.vertices, axis=1), body.radius_fn(coarse.vertices / np.linalg.norm(
        coarse.vertices, axis=1, keepdims=True)), rtol=1e-12)
    assert abs(mk.volume / m.volume - 1) < 0.01
    from renderlab.errors import UserError

    with pytest.raises(UserError, match="finer than the world"):     # no detail below the world's facet
        gravity_mesh(world, facet_m=1.0)


def test_polyhedron_field_of_the_body_far_and_laplacian(body):
    from renderlab.dynamics.polyhedron_gravity import PolyhedronGravity

    m = trimesh.Trimesh(body.vertices, body.faces, process=False)
    g = PolyhedronGravity(body.vertices, body.faces, gm_m3_s2=GM)
    c = m.center_mass
    np.testing.assert_allclose(g.centroid_m, c, atol=1e-9)
    r_max = float(np.linalg.norm(body.vertices - c, axis=1).max())
    d = np.random.default_rng(0).normal(size=(6, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    rn = 10 * r_max
    far = c + rn * d
    f = g.field(far)
    inertia = m.moment_inertia / m.mass                         # per unit mass (trimesh: density 1)

    def maccullagh(x):                                          # U = GM/r + GM (tr I - 3 I_rr) / (2 r^3)
        r = x - c
        n = np.linalg.norm(r)
        u = r / n
        return GM / n + GM * (np.trace(inertia) - 3 * u @ inertia @ u) / (2 * n**3)

    for p, a in zip(far, f.acceleration):
        a_pm = -GM * (p - c) / rn**3
        assert np.linalg.norm(a - a_pm) / np.linalg.norm(a_pm) < (r_max / rn) ** 2          # point-mass limit
        h = 1e-3 * rn
        a_q = np.array([(maccullagh(p + h * e) - maccullagh(p - h * e)) / (2 * h) for e in np.eye(3)])
        assert np.linalg.norm(a - a_q) / np.linalg.norm(a_pm) < 0.1 * (r_max / rn) ** 3     # + quadrupole
        # the one-point compiled path agrees with the vectorised one
        np.testing.assert_allclose(g.at(p)[1], a, rtol=1e-10)
    four_pi_g_rho = 4 * np.pi * g.g_rho
    # Laplacian: 0 outside (far and 1 m above the surface), -4 pi G rho inside (centre, 1 m under the surface)
    u = body.vertices[123] / np.linalg.norm(body.vertices[123])
    r_s = float(body.radius_fn(u[None])[0])
    lap_out = g.field(np.vstack([far, (r_s + 1.0) * u])).laplacian
    lap_in = g.field(np.vstack([c, (r_s - 1.0) * u])).laplacian
    assert np.abs(lap_out).max() < 1e-9 * four_pi_g_rho
    np.testing.assert_allclose(lap_in, -four_pi_g_rho, rtol=1e-9)


def test_closed_loop_flight_under_the_polyhedron_truth_runs_to_contact(tmp_path):
    from gnc_fixtures import TINY_GNC_SCENARIO as TINY

    from renderlab.campaign.cache import loaded_world
    from renderlab.dynamics.polyhedron_gravity import PolyhedronGravity
    from renderlab.scenario import load_scenario, scenario_from_dict, truth_dict
    from renderlab.studies.descent_gnc.study import Setup, run, section

    (tmp_path / "tiny.toml").write_text(TINY)
    sc, base = load_scenario(tmp_path / "tiny.toml", ['descent_gnc.methods=["spc"]', "descent_gnc.replay=false",
                                                      'descent_gnc.gravity="polyhedron"',
                                                      "descent_gnc.gravity_facet_m=8.0"])
    renderer = loaded_world(scenario_from_dict(truth_dict(sc.to_dict())), base)
    setup = Setup(renderer, section(sc))
    grav = setup.truth.gravity
    assert isinstance(grav, PolyhedronGravity) and grav.gm_m3_s2 == pytest.approx(GM, rel=1e-12)
    assert len(grav.F) == 20480                                   # level 5: 8 m facets on the ~200 m body
    t = run(sc, base, 0, np.random.SeedSequence(7), tmp_path / "work")
    r = t["gnc_runs"].to_pydict()
    assert r["method"] == ["spc"] and r["mode"] == ["closed"] and r["touchdown"] == [True]
    site = renderer.plan.model.site
    e, n, up = r["td_e_m"][0], r["td_n_m"][0], r["td_u_m"][0]
    assert abs(up - (site.height_at(e, n) - site.height_at(0.0, 0.0))) < 1e-6      # contact on the DEM
    assert np.hypot(e, n) < 3.0
