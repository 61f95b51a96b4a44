"""Polyhedron gravity (Werner & Scheeres 1997) against independent closed forms: a rectangular prism of uniform
density (the Nagy prism formula, written here), a finely tessellated sphere (GM/r outside), the Laplacian's
0 / −4πGρ outside / inside, and the EV5 shape's mass and centre of mass recovered from its field (Gauss's law and the
degree-1 moment) against trimesh's mass properties."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
import trimesh

from renderlab.dynamics.polyhedron_gravity import PolyhedronGravity
from renderlab.errors import UserError

LO, HI = np.array([-1.0, -0.7, -0.4]), np.array([1.5, 0.9, 0.6])


def _corners(P, lo, hi, axes=(0, 1, 2)):
    """(sign, X, Y, Z) over the 8 corners of the prism relative to the field point, coordinates in ``axes`` order."""
    for (i, x), (j, y), (k, z) in itertools.product(*[list(enumerate((lo[a] - P[a], hi[a] - P[a]))) for a in axes]):
        yield (1 if i else -1) * (1 if j else -1) * (1 if k else -1), x, y, z


def nagy_potential(P, lo, hi, g_rho):
    """U = Gρ∭dV/r of the prism [lo, hi] at P: D. Nagy, Geophysics 31, 362 (1966); Nagy, Papp & Benedek,
    J. Geodesy 74, 552 (2000), doi:10.1007/s001900000116 (the antiderivative evaluated at the 8 corners)."""
    total = 0.0
    for s, x, y, z in _corners(P, lo, hi):
        r = math.sqrt(x * x + y * y + z * z)
        total += s * (x * y * math.log(z + r) + y * z * math.log(x + r) + z * x * math.log(y + r)
                      - 0.5 * x * x * math.atan(y * z / (x * r)) - 0.5 * y * y * math.atan(z * x / (y * r))
                      - 0.5 * z * z * math.atan(x * y / (z * r)))
    return g_rho * total


def nagy_attraction(P, lo, hi, g_rho):
    """∇U of the prism (Nagy et al. 2000): a_z = −Gρ |||x ln(y + r) + y ln(x + r) − z atan(xy / zr)|||,
    the other axes by permutation."""
    out = np.zeros(3)
    for ax in range(3):
        b, c = [q for q in range(3) if q != ax]
        t = 0.0
        for s, x, y, z in _corners(P, lo, hi, (b, c, ax)):
            r = math.sqrt(x * x + y * y + z * z)
            t += s * (x * math.log(y + r) + y * math.log(x + r) - z * math.atan(x * y / (z * r)))
        out[ax] = -g_rho * t
    return out


def _box(lo, hi):
    box = trimesh.creation.box(extents=hi - lo)
    box.apply_translation((hi + lo) / 2)
    return box


def test_prism_matches_the_nagy_closed_form_outside_and_inside():
    box = _box(LO, HI)
    rho, G = 2000.0, 6.674e-11
    pg = PolyhedronGravity(box.vertices, box.faces, density_kg_m3=rho, G=G)
    pts = np.array([[2.3, 1.7, -1.9], [-3.1, 0.4, 0.9], [0.2, -0.1, 5.0], [0.31, 0.12, 0.07], [-0.6, 0.5, -0.3]])
    f = pg.field(pts)
    for k, P in enumerate(pts):
        u, a = nagy_potential(P, LO, HI, G * rho), nagy_attraction(P, LO, HI, G * rho)
        assert f.potential[k] == pytest.approx(u, rel=1e-12)
        np.testing.assert_allclose(f.acceleration[k], a, rtol=0, atol=1e-12 * np.linalg.norm(a))
        u1, a1 = pg.at(P)   # the compiled single-point path
        assert u1 == pytest.approx(u, rel=1e-12)
        np.testing.assert_allclose(a1, a, rtol=0, atol=1e-12 * np.linalg.norm(a))
    # the gradient matrix: central differences of the closed-form attraction (independent of eq. P3)
    P, h = pts[0], 1e-4
    fd = np.column_stack([(nagy_attraction(P + h * e, LO, HI, G * rho) - nagy_attraction(P - h * e, LO, HI, G * rho))
                          / (2 * h) for e in np.eye(3)])
    np.testing.assert_allclose(f.gradient[0], fd, atol=1e-7 * np.abs(fd).max())
    # Laplacian: 0 outside (solid angles sum to 0), −4πGρ inside (they sum to 4π)
    assert np.all(np.abs(f.laplacian[:3]) < 1e-14 * G * rho)
    np.testing.assert_allclose(f.laplacian[3:], -4 * math.pi * G * rho, rtol=1e-12)
    np.testing.assert_allclose(np.trace(f.gradient, axis1=1, axis2=2), f.laplacian, atol=1e-12 * G * rho)
    assert pg.mass_kg == pytest.approx(rho * np.prod(HI - LO), rel=1e-12)


def test_tessellated_sphere_is_a_point_mass_outside():
    """Icosphere of radius R: the field outside is GM/r of the sphere within the tessellation's volume error, and
    that of the polyhedron's own mass far closer (the icosahedral symmetry leaves no harmonic below degree 6)."""
    R, rho, G = 100.0, 1500.0, 6.674e-11
    ico = trimesh.creation.icosphere(subdivisions=4, radius=R)
    pg = PolyhedronGravity(ico.vertices, ico.faces, density_kg_m3=rho, G=G)
    v_sphere = 4.0 / 3.0 * math.pi * R**3
    vol_err = abs(pg.volume_m3 - v_sphere) / v_sphere
    assert 1e-4 < vol_err < 1e-2
    rng = np.random.default_rng(3)
    u = rng.normal(size=(40, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    r = rng.uniform(1.2 * R, 4 * R, 40)
    pts = u * r[:, None]
    f = pg.field(pts)
    gm_sphere, gm_poly = G * rho * v_sphere, G * rho * pg.volume_m3
    # the tessellation's error: its mass deficit (vol_err) and a non-spherical part of the same relative size whose
    # lowest harmonic is of degree 6, decaying as (R/r)^6
    tol = vol_err * (1 + (R / r) ** 6)
    a_sphere = -gm_sphere * pts / r[:, None] ** 3
    assert np.all(np.abs(f.potential * r / gm_sphere - 1) <= tol)
    assert np.all(np.linalg.norm(f.acceleration - a_sphere, axis=1) / np.linalg.norm(a_sphere, axis=1) <= tol)
    a_poly = -gm_poly * pts / r[:, None] ** 3
    assert np.all(np.abs(f.potential * r / gm_poly - 1) <= vol_err * (R / r) ** 6)
    assert np.all(np.linalg.norm(f.acceleration - a_poly, axis=1) / np.linalg.norm(a_poly, axis=1)
                  <= vol_err * (R / r) ** 6)
    assert np.all(np.abs(f.laplacian) < 1e-12 * G * rho)
    inside = pg.field(0.9 * R * u[:5]).laplacian
    np.testing.assert_allclose(inside, -4 * math.pi * G * rho, rtol=1e-12)


def _gauss_legendre_sphere(n: int):
    """Nodes (unit vectors) and weights of a product rule on the sphere, exact for harmonics up to degree 2n − 1."""
    x, wx = np.polynomial.legendre.leggauss(n)
    phi = 2 * np.pi * np.arange(2 * n) / (2 * n)
    ct, ph = np.meshgrid(x, phi, indexing="ij")
    st = np.sqrt(1 - ct**2)
    u = np.stack([st * np.cos(ph), st * np.sin(ph), ct], -1).reshape(-1, 3)
    w = (wx[:, None] * np.full(2 * n, 2 * np.pi / (2 * n))[None]).reshape(-1)
    return u, w


def test_ev5_shape_mass_and_centre_from_the_field_match_trimesh():
    """Procedural EV5 (32 m facets): Gauss's law ∮ ∇U·dA = −4πGM and the degree-1 moment ∮ U û dΩ = 4π/3 GM c / R²
    on a sphere around the body give the mass and centre of mass trimesh computes from the mesh."""
    from renderlab.worlds.ev5 import stream
    from renderlab.worlds.ev5.config import EV5World
    from renderlab.worlds.ev5.shape import procedural_shape

    shape = procedural_shape(EV5World(seed=5, facet_m=32.0), stream(5, "shape"))
    rho, G = 1300.0, 6.674e-11
    pg = PolyhedronGravity(shape.vertices, shape.faces, density_kg_m3=rho, G=G)
    tm = trimesh.Trimesh(shape.vertices, shape.faces, process=False)
    assert tm.is_watertight and tm.is_winding_consistent
    tm.density = rho
    R = 3.0 * float(np.linalg.norm(shape.vertices, axis=1).max())
    u, w = _gauss_legendre_sphere(20)
    f = pg.field(R * u)
    flux = R**2 * np.sum(w * np.einsum("ni,ni->n", f.acceleration, u))
    assert -flux / (4 * math.pi * G) == pytest.approx(tm.mass, rel=1e-9)
    centre = 3 * R**2 / (4 * math.pi * G * tm.mass) * (w[:, None] * f.potential[:, None] * u).sum(0)
    np.testing.assert_allclose(centre, tm.center_mass, atol=1e-6 * np.linalg.norm(tm.extents))
    assert np.linalg.norm(tm.center_mass) > 0.1   # a centre off the origin: the check is not trivially zero
    np.testing.assert_allclose(pg.centroid_m, tm.center_mass, atol=1e-9 * np.linalg.norm(tm.extents))


def test_gm_option_and_refusals():
    box = _box(LO, HI)
    pg = PolyhedronGravity(box.vertices, box.faces, gm_m3_s2=2.9)
    assert pg.gm_m3_s2 == pytest.approx(2.9)
    flipped = PolyhedronGravity(box.vertices, box.faces[:, ::-1], gm_m3_s2=2.9)   # inward winding is flipped
    np.testing.assert_allclose(flipped.acceleration([3.0, 2.0, 1.0]), pg.acceleration([3.0, 2.0, 1.0]), rtol=1e-14)
    with pytest.raises(UserError, match="not closed"):
        PolyhedronGravity(box.vertices, box.faces[:-1], gm_m3_s2=1.0)
    bad = box.faces.copy()
    bad[0] = bad[0, ::-1]
    with pytest.raises(UserError, match="oriented"):
        PolyhedronGravity(box.vertices, bad, gm_m3_s2=1.0)
    with pytest.raises(UserError, match="exactly one"):
        PolyhedronGravity(box.vertices, box.faces)
