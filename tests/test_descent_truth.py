"""Truth dynamics of the lander in the rotating asteroid-fixed frame: the closed-form Kepler orbit seen from the
spinning frame, the Jacobi integral over an orbit (point mass + J2 and polyhedron), the J2 field against the descent
study's own implementation, and contact with the site DEM and with the shape mesh (trimesh's closest point)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from renderlab.dynamics.descent_truth import ContactSurface, DescentTruth, PointMassJ2, make_gravity
from renderlab.errors import UserError

GM, OMEGA = 2.9, 2 * math.pi / (3.725 * 3600)
EL = dict(a=520.0, e=0.12, i=math.radians(40.0), raan=0.3, argp=1.1)


def _kepler_inertial(t):
    """Closed-form two-body state (inertial) at times ``t`` from the elements EL (mean anomaly 0 at t = 0)."""
    from renderlab.dynamics.orbits import solve_kepler, state_from_elements

    n = math.sqrt(GM / EL["a"] ** 3)
    E = solve_kepler(n * np.asarray(t, float), EL["e"])
    nu = 2 * np.arctan2(math.sqrt(1 + EL["e"]) * np.sin(E / 2), math.sqrt(1 - EL["e"]) * np.cos(E / 2))
    return state_from_elements(EL["a"], EL["e"], EL["i"], EL["raan"], EL["argp"], nu, mu=GM)


def _to_body(r, v, t):
    """Inertial → body frame turning at ω about z (body = inertial at t = 0): r_B = Rz(−ωt) r, v_B = Rz(−ωt)(v − ω×r)."""
    c, s = np.cos(OMEGA * t), np.sin(OMEGA * t)
    w = np.array([0, 0, OMEGA])
    vr = v - np.cross(w, r)
    rot = lambda a: np.stack([c * a[..., 0] + s * a[..., 1], -s * a[..., 0] + c * a[..., 1], a[..., 2]], -1)  # noqa: E731
    return rot(r), rot(vr)


def _orbit_start():
    r0, v0 = _kepler_inertial(np.array([0.0]))
    rb, vb = _to_body(r0[0], v0[0], 0.0)
    return np.r_[rb, vb], 2 * math.pi * math.sqrt(EL["a"] ** 3 / GM)


def test_rotating_frame_motion_is_the_kepler_orbit_seen_turning():
    x0, period = _orbit_start()
    t = np.linspace(0, period, 41)
    states = DescentTruth(PointMassJ2(GM), OMEGA, rtol=1e-12, atol_m=1e-10).coast(0.0, x0, t)
    r_i, v_i = _kepler_inertial(t)
    rb, vb = _to_body(r_i, v_i, t)
    np.testing.assert_allclose(states[:, :3], rb, atol=1e-6)
    np.testing.assert_allclose(states[:, 3:], vb, atol=1e-9)
    # a frame turning the wrong way (Coriolis and centrifugal of −ω) leaves the orbit by kilometres
    wrong = DescentTruth(PointMassJ2(GM), -OMEGA).coast(0.0, np.r_[x0[:3], vb[0] + 2 * np.cross([0, 0, OMEGA], x0[:3])], t)
    assert np.abs(wrong[:, :3] - rb).max() > 100.0


@pytest.mark.parametrize("j2", [0.0, 0.05])
def test_jacobi_integral_is_conserved_with_point_mass_and_j2(j2):
    x0, period = _orbit_start()
    truth = DescentTruth(PointMassJ2(GM, j2, 200.0), OMEGA, rtol=1e-12, atol_m=1e-10)
    states = truth.coast(0.0, x0, np.linspace(0, period, 60))
    J = np.array([truth.jacobi(x) for x in states])
    assert np.abs(J - J[0]).max() <= 1e-9 * abs(J[0])
    # and it is not conserved when the frame's spin is left out of J (the check can fail)
    inertial_like = 0.5 * np.einsum("ni,ni->n", states[:, 3:], states[:, 3:]) - [truth.gravity.at(x[:3])[0] for x in states]
    assert np.ptp(inertial_like) > 1e-4 * abs(J[0])


def test_j2_field_equals_the_descent_studys_and_is_the_gradient_of_its_potential():
    from renderlab.studies.descent_navigation.truth import TrueDescent

    pm = PointMassJ2(GM, 0.05, 200.0)
    ref = TrueDescent(None, OMEGA, np.zeros(3), np.array([0, 0, 1.0]), GM, 0.05, 200.0)
    rng = np.random.default_rng(1)
    for r in rng.normal(size=(5, 3)) * 300:
        np.testing.assert_allclose(pm.at(r)[1], ref.gravity(r), rtol=1e-13)
        h = 1e-3
        fd = [(pm.at(r + h * e)[0] - pm.at(r - h * e)[0]) / (2 * h) for e in np.eye(3)]
        np.testing.assert_allclose(pm.at(r)[1], fd, rtol=1e-7)


def test_jacobi_integral_is_conserved_in_the_polyhedron_field():
    from renderlab.worlds.ev5 import stream
    from renderlab.worlds.ev5.config import EV5World
    from renderlab.worlds.ev5.shape import procedural_shape

    shape = procedural_shape(EV5World(seed=5, facet_m=32.0), stream(5, "shape"))
    grav = make_gravity("polyhedron", gm_m3_s2=GM, vertices=shape.vertices, faces=shape.faces)
    truth = DescentTruth(grav, OMEGA, rtol=1e-12, atol_m=1e-10)
    x0, period = _orbit_start()
    states = truth.coast(0.0, x0, np.linspace(0, period, 30))
    J = np.array([truth.jacobi(x) for x in states])
    assert np.abs(J - J[0]).max() <= 1e-9 * abs(J[0])
    # the polyhedron's orbit is not the point mass's (the field's irregular part acts)
    pm = DescentTruth(PointMassJ2(GM), OMEGA, rtol=1e-12, atol_m=1e-10).coast(0.0, x0, [0.0, period])
    assert np.linalg.norm(pm[-1, :3] - states[-1, :3]) > 1.0


class _PlaneSite:
    """A landing-site DEM with the attributes of renderlab.worlds.ev5.site.Site: gentle analytic bumps on a grid."""

    def __init__(self, origin, R, half=10.0, cell=0.25):
        from renderlab.worlds.ev5 import terrain

        self.origin_m, self.R_body_from_site, self.cell_m = origin, R, cell
        n = int(round(2 * half / cell)) + 1
        self.x0_m = -half
        t = self.x0_m + np.arange(n) * cell
        X, Y = np.meshgrid(t, t)
        self.heights_m = 0.3 * np.sin(X / 3.0) * np.cos(Y / 4.0) - 0.002 * (X**2 + Y**2)
        self._interp = terrain.grid_interp

    def height_at(self, x, y):
        return self._interp(self.heights_m, self.x0_m, self.cell_m, x, y)


def test_contact_with_the_site_dem_and_with_the_mesh():
    R_body = 150.0
    ico = trimesh.creation.icosphere(subdivisions=4, radius=R_body)
    u = np.array([0.3, 0.5, 0.6])
    u /= np.linalg.norm(u)
    surf0 = ContactSurface(ico.vertices, ico.faces)
    origin = u * (surf0.mesh_radius(u) + 0.5)
    east = np.cross([0, 0, 1.0], u)
    east /= np.linalg.norm(east)
    R = np.column_stack([east, np.cross(u, east), u])
    site = _PlaneSite(origin, R)
    surface = ContactSurface(ico.vertices, ico.faces, site)
    truth = DescentTruth(PointMassJ2(GM), OMEGA, surface)
    # over the site: drop along −normal, contact on the DEM
    x0 = np.r_[site.origin_m + R @ [1.3, -2.1, 6.0], -0.4 * u]
    st = truth.step(0.0, x0, 200.0)
    s = (st.x[:3] - origin) @ R
    assert st.contact and 10.0 < st.t_s < 20.0
    assert abs(s[2] - float(site.height_at(s[0], s[1]))) < 1e-8
    assert np.dot(st.x[3:], u) < 0
    # away from the site: radial drop onto the sphere mesh; the contact point is on the mesh (trimesh's oracle)
    d = np.array([-0.7, 0.1, -0.2])
    d /= np.linalg.norm(d)
    st2 = truth.step(5.0, np.r_[d * (R_body + 3.0), -0.3 * d], 100.0)
    tri = ico.vertices[ico.faces]
    closest = trimesh.triangles.closest_point(tri, np.repeat(st2.x[None, :3], len(tri), axis=0))
    assert st2.contact and np.linalg.norm(closest - st2.x[:3], axis=1).min() < 1e-7
    # no contact within the step: the state at t1, equal to the step in two halves
    a = np.array([1e-4, -2e-4, 3e-4])
    whole = truth.step(0.0, x0, 2.0, a)
    half = truth.step(1.0, truth.step(0.0, x0, 1.0, a).x, 2.0, a)
    assert not whole.contact and whole.t_s == 2.0
    np.testing.assert_allclose(whole.x, half.x, atol=1e-9)
    with pytest.raises(UserError, match="forward"):
        truth.step(2.0, x0, 1.0)
    with pytest.raises(UserError, match="unknown truth gravity"):
        make_gravity("mascons", gm_m3_s2=1.0)
