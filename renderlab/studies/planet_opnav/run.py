"""One run of study ``planet_opnav``: every grid cell rendered once with the run's seeds, measured by every method.

Per cell (``[planet_opnav]``: range × phase angle × photometric law, :mod:`.config`) the camera sits at the cell's
range and phase angle in the plane of the world's ``[sun] direction`` and ``trajectory.up`` (the ``planet_approach``
geometry of :func:`renderlab.worlds.planet.path.approach_poses`, the body centre ``offset_deg`` off the boresight);
the image is rendered through :class:`renderlab.pipeline.frame_api.Renderer` (``world.law`` set to the cell's law)
with a seed of its own drawn from the run's seed sequence, so runs are independent draws of render and sensor noise.
The a-priori position is the true one plus N(0, (``apriori_sigma_frac`` · range)²) per axis (the same draw for every
method); the attitude and the body model are known. Each image goes through every method by the kind's runner
(:func:`renderlab.measurement.centre_limb_runner.runner`) and gives one row of the ``centre_limb`` table
(:mod:`renderlab.contracts.centre_limb_table`) with the grid columns ``cell``, ``law``, ``range_nominal_m``,
``phase_nominal_deg`` and ``draw`` (the run).
"""

from __future__ import annotations

import itertools
from types import SimpleNamespace

import numpy as np

from renderlab.errors import UserError


def config(scenario):
    from renderlab.studies.planet_opnav.config import PlanetOpNavConfig

    return getattr(scenario, "planet_opnav", None) or PlanetOpNavConfig()


def check(scenario) -> None:
    """Refuse what the study cannot run (a world other than ``planet``, an unknown method), before any output."""
    from renderlab import plugins

    if scenario.world.kind != "planet":
        raise UserError(f"study planet_opnav needs world.kind 'planet', got '{scenario.world.kind}'")
    reg = plugins.method_registry("centre_limb")
    for name in config(scenario).methods:
        if name not in reg:
            raise reg.unknown(name, "planet_opnav.methods: ")


def cells(cfg) -> list[dict]:
    """The grid cells in order: law, then range, then phase."""
    grid = itertools.product(cfg.laws, cfg.ranges_m, cfg.phases_deg)
    return [{"cell": k, "law": law, "range_nominal_m": float(rng), "phase_nominal_deg": float(ph)}
            for k, (law, rng, ph) in enumerate(grid)]


def cell_pose(scenario, cfg, cell: dict, centre_m):
    """The camera pose (render frame) of a cell."""
    from renderlab.worlds.planet.path import approach_poses

    t = scenario.trajectory
    traj = SimpleNamespace(up=getattr(t, "up", [0.0, 0.0, 1.0]), phase_plane_deg=getattr(t, "phase_plane_deg", 0.0),
                           range_start_m=cell["range_nominal_m"], range_end_m=None, frames=1,
                           phase_start_deg=cell["phase_nominal_deg"], phase_end_deg=None, offset_deg=cfg.offset_deg,
                           dt_s=1.0)
    return approach_poses(traj, np.asarray(scenario.sun.direction, float), centre_m)[0]


def body_model(scenario, base_dir):
    """The body as the methods know it (:class:`~renderlab.contracts.centre_limb.BodyModel`, body frame = the
    world's render frame)."""
    from renderlab.contracts.centre_limb import BodyModel
    from renderlab.worlds.planet.body import build_body

    b = build_body(scenario.world)
    return BodyModel(semi_axes_m=np.asarray(b.semi_axes_m, float), R_body_from_principal=b.R_render_from_principal,
                     centre_m=np.asarray(b.centre_m, float))


def run(scenario, base_dir, run_index: int, seed_sequence, workdir) -> dict:
    """One run → ``{"centre_limb": table}`` (module docstring)."""
    import pyarrow as pa

    from renderlab import plugins
    from renderlab.contracts.centre_limb_table import CENTRE_LIMB_KNOWN
    from renderlab.contracts.schemas import table_from_rows
    from renderlab.measurement.centre_limb_runner import from_render, runner
    from renderlab.pipeline.frame_api import Renderer

    check(scenario)
    cfg = config(scenario)
    reg = plugins.method_registry("centre_limb")
    methods = [reg.get(n)() for n in cfg.methods]
    body = body_model(scenario, base_dir)
    grid = cells(cfg)
    seeds = seed_sequence.spawn(len(grid))
    rows: list[dict] = []
    for law in cfg.laws:
        with Renderer(scenario, base_dir, overrides=[f"world.law={law}"]) as r:
            for cell in (c for c in grid if c["law"] == law):
                render_ss, prior_ss = seeds[cell["cell"]].spawn(2)
                pose = cell_pose(scenario, cfg, cell, body.centre_m)
                f = r.frame(0, pose=pose, seed=int(render_ss.generate_state(1)[0]), outputs=("dn", "truth"))
                sigma = cfg.apriori_sigma_frac * float(np.linalg.norm(pose.position_m - body.centre_m))
                prior = pose.position_m + np.random.default_rng(prior_ss).normal(size=3) * sigma
                item = from_render(f, prior, body, seed=cell["cell"], extra={**cell, "draw": int(run_index)})
                for m in methods:
                    rows += runner(m, [item])
    schema = pa.schema([f for f in CENTRE_LIMB_KNOWN if f.name not in ("campaign", "run")])  # the engine adds them
    return {"centre_limb": table_from_rows(rows, schema, "centre_limb")}
