"""Polyhedron truth gravity on an EV5 world: why the rendered mesh is open, and cost / error of the closed mesh.

Explains the polyhedron paragraph of ``results/descent_gnc/README.md``. For the world of a scenario file it prints
(1) trimesh's verdict on the rendered (site-cut) global mesh and on the uncut gravity body
(:func:`renderlab.worlds.ev5.gravity_mesh.gravity_mesh`): watertight, winding, volume, Euler number, one-face edges;
(2) the facet and edge counts of the gravity mesh at the world's facet size and coarser ones (their seconds per
acceleration: ``benchmarks/bench_polyhedron_gravity.py``); (3) the acceleration error of each coarser mesh against the world-facet mesh at points above the site along its normal (the descent's
altitudes), and the point mass + J2 truth of the study's defaults beside them; (4) what the gravity body leaves out,
the site DEM's detail (heights minus the global base surface), as one mass point per DEM cell (cell² × detail at
half the detail's height; an estimate, crude where the height is not large against the detail).

    .venv/bin/python investigations/descent_gnc/gravity_mesh_probe.py results/descent_gnc/scenario.toml
"""

from __future__ import annotations

import argparse
import tomllib
from pathlib import Path

import numpy as np


def _mesh_report(name, v, f):
    import trimesh

    m = trimesh.Trimesh(v, f, process=False)
    e = np.sort(m.edges, axis=1)
    _, c = np.unique(e, axis=0, return_counts=True)
    print(f"{name}: faces {len(f)}, edges {len(c)}, one-face edges {(c == 1).sum()}, watertight {m.is_watertight}, "
          f"winding consistent {m.is_winding_consistent}, volume {m.volume:.6g} m^3, Euler {m.euler_number}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenario", type=Path, help="scenario TOML with an EV5 [world]")
    ap.add_argument("--coarse", type=float, nargs="*", default=[4.0, 8.0, 16.0], help="coarser facet sizes, m")
    ap.add_argument("--heights", type=float, nargs="*", default=[200, 100, 50, 20, 10, 5, 2, 0.5],
                    help="heights above the site origin along its normal, m")
    ap.add_argument("--gm", type=float, default=2.9, help="GM of the body, m^3/s^2")
    a = ap.parse_args(argv)

    from renderlab.dynamics.descent_truth import PointMassJ2
    from renderlab.dynamics.polyhedron_gravity import PolyhedronGravity
    from renderlab.worlds.ev5 import stream
    from renderlab.worlds.ev5.config import EV5World
    from renderlab.worlds.ev5.gravity_mesh import gravity_mesh
    from renderlab.worlds.ev5.shape import procedural_shape
    from renderlab.worlds.ev5.site import build_site

    world = EV5World(**tomllib.loads(a.scenario.read_text())["world"])
    full = procedural_shape(world, stream(world.seed, "shape"))
    site, cut = build_site(full, world.site, world.facet_m, stream(world.seed, "terrain"), stream(world.seed, "boulders"))
    _mesh_report("rendered global mesh (cut under the site)", cut.vertices, cut.faces)
    fine = gravity_mesh(world, a.scenario.parent)
    _mesh_report(f"gravity mesh at the world's facet {world.facet_m:g} m", fine.vertices, fine.faces)
    print("gravity mesh vertices == rendered shape's before the cut, bit for bit:",
          fine.vertices.tobytes() == full.vertices.tobytes(), "; faces equal:", np.array_equal(fine.faces, full.faces))
    n_hat = site.R_body_from_site[:, 2]
    pts = site.origin_m[None] + np.asarray(a.heights)[:, None] * n_hat[None]
    fields = {}
    for facet in [world.facet_m, *a.coarse]:
        g = gravity_mesh(world, a.scenario.parent, None if facet == world.facet_m else facet)
        grav = PolyhedronGravity(g.vertices, g.faces, gm_m3_s2=a.gm)
        fields[facet] = np.array([grav.at(p)[1] for p in pts])
        print(f"facet {facet:g} m: {len(g.faces)} faces, {len(grav.E)} edges")
    ref = fields[world.facet_m]
    pm = PointMassJ2(a.gm, 0.05, 200.0)
    print("height_m | |a| world-facet m/s^2 | " + " | ".join(f"rel err {f:g} m" for f in a.coarse)
          + " | rel diff point mass + J2")
    for i, h in enumerate(a.heights):
        rel = [np.linalg.norm(fields[f][i] - ref[i]) / np.linalg.norm(ref[i]) for f in a.coarse]
        rel_pm = np.linalg.norm(pm.at(pts[i])[1] - ref[i]) / np.linalg.norm(ref[i])
        print(f"{h:g} | {np.linalg.norm(ref[i]):.5g} | " + " | ".join(f"{r:.3g}" for r in rel) + f" | {rel_pm:.3g}")
    _detail_estimate(world, full, site, pts, a.heights, ref, a.gm / fine.volume())
    return 0


def _detail_estimate(world, full, site, pts, heights, ref, g_rho):
    """Point (4) of the module docstring: |δa| / |a| of the site detail the gravity body omits."""
    from renderlab.worlds.ev5.site import _base_surface, _patch_grid

    g = _patch_grid(world.site)
    _, _, base, _ = _base_surface(full, site.origin_m, site.R_body_from_site, g, world.facet_m, world.site)
    detail = site.heights_m - base
    t = g.x0 + np.arange(g.n) * g.cell
    xs, ys = np.meshgrid(t, t)
    q = site.to_body(np.stack([xs, ys, base + 0.5 * detail], -1)).reshape(-1, 3)
    m = g_rho * g.cell**2 * detail.reshape(-1)                # G dm of each cell, m^3/s^2 (negative: a hollow)
    print(f"site detail: {detail.min():.3g} .. {detail.max():.3g} m, net volume {detail.sum() * g.cell**2:.4g} m^3")
    for p, h, a_ref in zip(pts, heights, ref):
        d = q - p
        da = (m[:, None] * d / np.linalg.norm(d, axis=1, keepdims=True) ** 3).sum(0)
        print(f"  {h:g} m above the site origin: |delta a| / |a| = {np.linalg.norm(da) / np.linalg.norm(a_ref):.3g}")


if __name__ == "__main__":
    raise SystemExit(main())
