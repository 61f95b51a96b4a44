"""Seconds per truth acceleration of the descent study's gravity options, side by side in one run.

Usage::

    .venv/bin/python benchmarks/bench_polyhedron_gravity.py SCENARIO.toml [--coarse 4 8 16] [--flight]

For the EV5 world of ``SCENARIO.toml``: the point mass + J2 truth and the polyhedron field
(:class:`~renderlab.dynamics.polyhedron_gravity.PolyhedronGravity`) of the closed gravity body
(:func:`renderlab.worlds.ev5.gravity_mesh.gravity_mesh`) at the world's facet size and at each ``--coarse`` size.
Timed: ``gravity.at(r)`` (the integrator's path: one point, compiled kernel, Python call included) at points 200 m
... 0.5 m above the site along its normal, ``--rounds`` rounds in which every option runs one batch in turn (so a
load change hits all alike); printed: the median ms per evaluation, its ratio to the point mass + J2 and to the
world-facet polyhedron. With ``--flight`` (the scenario needs a ``[descent_gnc]`` section; its world is built) the
study's nominal flight (perfect navigation, ideal thrusters, to contact) is flown under each option: wall seconds
and gravity evaluations per flight. The load average is printed before and after.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
import tomllib
from pathlib import Path

import numpy as np


def _options(world, base, coarse, gm, j2, r_ref):
    from renderlab.dynamics.descent_truth import PointMassJ2
    from renderlab.dynamics.polyhedron_gravity import PolyhedronGravity
    from renderlab.worlds.ev5.gravity_mesh import gravity_mesh

    out = {"point mass + J2": PointMassJ2(gm, j2, r_ref)}
    for facet in [None, *coarse]:
        body = gravity_mesh(world, base, facet)
        out[f"polyhedron {world.facet_m if facet is None else facet:g} m, {len(body.faces)} faces"] = \
            PolyhedronGravity(body.vertices, body.faces, gm_m3_s2=gm)
    return out


def _flight(path: Path, options: dict, coarse) -> None:
    from renderlab.campaign.cache import loaded_world
    from renderlab.dynamics.closed_loop import fly
    from renderlab.scenario import load_scenario, scenario_from_dict, truth_dict
    from renderlab.studies.descent_gnc.study import Setup, section

    facets = [None, *coarse]
    poly = ['descent_gnc.gravity="polyhedron"']
    overrides = [[]] + [poly + ([] if f is None else [f"descent_gnc.gravity_facet_m={f}"]) for f in facets]
    for name, ov in zip(options, overrides):
        sc, base = load_scenario(path, ov)
        s = Setup(loaded_world(scenario_from_dict(truth_dict(sc.to_dict())), base), section(sc))
        s.truth.gravity = counted = _Counted(s.truth.gravity)
        t = time.perf_counter()
        f = fly(s.truth, s.guidance(), s.t0, s.x0, control_period_s=s.cfg.control_period_s, t_max_s=s.t_max,
                thrusters=s.thrusters(None))
        wall = time.perf_counter() - t
        print(f"flight, {name}: {wall:.2f} s wall, {counted.n} gravity evaluations, contact at t = {f.t_s[-1]:.3f} s",
              flush=True)


class _Counted:
    """A gravity field that counts its ``at`` calls."""

    def __init__(self, inner):
        self.inner, self.n = inner, 0

    def at(self, r):
        self.n += 1
        return self.inner.at(r)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("scenario", type=Path)
    ap.add_argument("--coarse", type=float, nargs="*", default=[4.0, 8.0, 16.0], help="coarser facet sizes, m")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--batch-s", type=float, default=0.3, help="about this many seconds per option and round")
    ap.add_argument("--flight", action="store_true", help="also fly the study's nominal descent under each option")
    a = ap.parse_args(argv)
    from renderlab.worlds.ev5.config import EV5World

    doc = tomllib.loads(a.scenario.read_text())
    world = EV5World(**doc["world"])
    gnc = doc.get("descent_gnc", {})
    print(f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}", flush=True)
    opts = _options(world, a.scenario.parent, a.coarse, gnc.get("gm_true_m3_s2", 2.9), gnc.get("j2_true", 0.05),
                    gnc.get("r_ref_m", 200.0))
    # points above the body along a mid-latitude direction at the descent's heights (the site needs the world build)
    u = np.array([0.6, 0.0, 0.8])
    r0 = float((opts[list(opts)[1]].vertices @ u).max())
    pts = [(r0 + h) * u for h in (200, 100, 50, 20, 10, 5, 2, 0.5)]
    n = {}
    for name, g in opts.items():                       # warm (compile) and size a batch to ~batch_s
        g.at(pts[0])
        t = time.perf_counter()
        g.at(pts[1])
        n[name] = max(3, int(a.batch_s / max(time.perf_counter() - t, 1e-6)))
    times = {k: [] for k in opts}
    for _ in range(a.rounds):
        for name, g in opts.items():
            t = time.perf_counter()
            for k in range(n[name]):
                g.at(pts[k % len(pts)])
            times[name].append((time.perf_counter() - t) / n[name])
    med = {k: statistics.median(v) for k, v in times.items()}
    names = list(opts)
    print(f"{'option':40s} {'ms per acceleration':>20s} {'x point mass':>13s} {'/ world-facet poly':>19s}")
    for k in names:
        print(f"{k:40s} {med[k] * 1e3:20.4g} {med[k] / med[names[0]]:13.3g} {med[k] / med[names[1]]:19.3g}")
    if a.flight:
        _flight(a.scenario, opts, a.coarse)
    print(f"load average at the end {os.getloadavg()[0]:.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
