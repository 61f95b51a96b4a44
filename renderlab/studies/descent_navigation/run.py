"""Study ``descent_navigation``: one Monte Carlo run, each landmark method (:mod:`.loop`) and measurement source
(:mod:`.sources`) driving the descent EKF closed-loop on the cached truth render re-exposed with the run's noise, with
the run's own initial estimate, star-tracker and accelerometer draws (docs/descent_navigation.md, "One run")."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from renderlab import plugins
from renderlab.campaign.cache import cached_truthset
from renderlab.campaign.maplets import respaced_maplets
from renderlab.campaign.reexpose import ReexposedTruthSet
from renderlab.campaign.run_truth import truth_perturbations_on
from renderlab.errors import UserError
from renderlab.files.truthset import TruthSet
from renderlab.measurement.runner import MeasureOptions, make_method, onboard_photometry
from renderlab.scenario import scenario_from_dict, truth_dict
from renderlab.sensor.model import SensorOptions
from renderlab.studies.descent_navigation.config import DescentNavigationConfig
from renderlab.studies.descent_navigation.loop import RunInputs, run_method
from renderlab.studies.descent_navigation.sources import LandmarkMethodSource
from renderlab.studies.descent_navigation.truth import planned_descent, true_descent, truthset_frames
from renderlab.worlds.ev5.catalog import read_catalog


def section(scenario):
    """The scenario's ``[descent_navigation]`` section (defaults when absent)."""
    return getattr(scenario, "descent_navigation", None) or DescentNavigationConfig()


def check(scenario) -> None:
    """Refuse what the study cannot run, before any output: world, trajectory, truth perturbations, names."""
    if scenario.world.kind != "ev5" or scenario.trajectory.kind != "ev5_descent":
        raise UserError(f"study descent_navigation needs world.kind 'ev5' with an 'ev5_descent' trajectory, got "
                        f"'{scenario.world.kind}'")
    p = scenario.perturbations
    on = truth_perturbations_on(p)
    if on:
        raise UserError(f"study descent_navigation renders the nominal descent once; perturbations.{on[0]} is not "
                        "supported (the study disperses the initial estimate and the sensors)")
    cfg = section(scenario)
    for name in cfg.methods:
        plugins.landmark_methods.get(name, where="descent_navigation.methods: ")
    for src in cfg.sources:
        plugins.measurement_sources.get(src.kind, where=f"descent_navigation.sources '{src.name}': ")
    plugins.filters.get(cfg.filter, where="descent_navigation.filter: ")


def filter_options(cfg, omega_rad_s: float) -> dict:
    """The onboard filter's options: its own GM (no J2), the spin, the process and input noise, the gate."""
    return {"gm_m3_s2": cfg.gm_filter_m3_s2, "omega_rad_s": (0.0, 0.0, omega_rad_s), "q_acc_m2_s3": cfg.q_acc_m2_s3,
            "sigma_input_mps2": cfg.accel_sigma_mps2, "gate_probability": cfg.gate_probability,
            "reject_flagged": cfg.reject_flagged, "max_step_s": 10.0, "map_states": cfg.map_states,
            "map_keep_updates": cfg.map_keep_updates, "joint_gate": cfg.joint_gate,
            "iterations": cfg.iterations}


def run_draws(truth, times, R_true, cfg, ss) -> dict:
    """The run's initial estimate ``x0`` (P0), star tracker ``R_star`` (K, 3, 3) and accelerometer ``accel`` (per
    image k: the samples [(t0, t1, u)] from the previous image, none for k = 0); ``ss`` = (x0, star, accel) seeds."""
    from scipy.spatial.transform import Rotation

    ss_x0, ss_st, ss_acc = ss
    sig_st = math.radians(cfg.star_tracker_sigma_arcsec / 3600.0)
    dth = np.random.default_rng(ss_st).standard_normal((len(times), 3)) * sig_st
    R_star = np.einsum("kij,kjl->kil", R_true, Rotation.from_rotvec(dth).as_matrix())
    sd0 = np.r_[np.full(3, cfg.initial_position_sigma_m), np.full(3, cfg.initial_velocity_sigma_mps)]
    x0 = truth.state(times[0]) + np.random.default_rng(ss_x0).standard_normal(6) * sd0
    spans = []
    for a, b in zip(times[:-1], times[1:]):
        edges = np.linspace(a, b, max(1, int(math.ceil((b - a) * cfg.accel_rate_hz - 1e-9))) + 1)
        spans.append(np.stack([edges[:-1], edges[1:]], 1))
    allspans = np.concatenate(spans) if spans else np.zeros((0, 2))
    u = truth.accelerometer(allspans[:, 0], allspans[:, 1], cfg.accel_sigma_mps2, np.random.default_rng(ss_acc))
    accel, j = [[]], 0
    for sp in spans:
        accel.append([(float(t0), float(t1), u[j + i]) for i, (t0, t1) in enumerate(sp)])
        j += len(sp)
    return {"x0": x0, "P0": np.diag(sd0**2), "R_star": R_star, "accel": accel, "sigma_st": sig_st}


def run_inputs(ts, frames, truth, maplets, cfg, scenario, run_index, ss) -> object:
    """The run's shared :class:`~renderlab.studies.descent_navigation.loop.RunInputs` (every draw from ``ss``);
    ``frames`` as :func:`~renderlab.studies.descent_navigation.truth.planned_descent` gives them, ``ts`` the
    re-exposed truth set (None when no source needs images)."""
    d = run_draws(truth, frames["times"], frames["R_true"], cfg, ss)
    return RunInputs(ts=ts, truth=truth, maplets=maplets, centres=np.array([m.center_m for m in maplets], float),
                     spacing=np.array([m.spacing_m for m in maplets], float), R_site=frames["R_site"],
                     times=frames["times"], R_true=frames["R_true"], pos_true=frames["pos_true"],
                     cameras=frames["cameras"], R_star=d["R_star"], accel=d["accel"], x0=d["x0"], P0=d["P0"],
                     sigma_st_rad=d["sigma_st"], campaign=scenario.name, run=int(run_index))


def _rendered_inputs(scenario, base_dir, workdir, cfg, ss_noise, ss_map):
    """(re-exposed truth set, frames, truth, maplets, onboard L table) of the rendered path (module docstring)."""
    truth_sc = scenario_from_dict(truth_dict(scenario.to_dict()), "descent_navigation truth scenario")
    path, _ = cached_truthset(truth_sc, Path(base_dir), Path(workdir) / "truth_cache")
    ts0 = TruthSet.open(path)
    noise_seeds = [int(s.generate_state(1)[0]) for s in ss_noise.spawn(len(ts0))]
    ts = ReexposedTruthSet(ts0, SensorOptions(**scenario.sensor.options_dict()), noise_seeds, cache=True)
    maplets = read_catalog(path)
    if cfg.map_realisation == "per_run":
        maplets = respaced_maplets(maplets, scenario.world, base_dir, 1.0, np.random.default_rng(ss_map))
    return ts, truthset_frames(ts0), true_descent(ts0, scenario, cfg), maplets, ts0


def run(scenario, base_dir, run_index: int, seed_sequence, workdir) -> dict:
    """One run of ``descent_navigation`` → ``{"descent_filter": table, "descent_landmarks": table}``. Without a
    source that needs images (only geometric ``sources``) nothing is rendered: the frames come from the world's plan.
    """
    check(scenario)
    cfg = section(scenario)
    # the first five children as before the geometric sources; the sixth draws their injected errors
    ss_noise, ss_x0, ss_st, ss_acc, ss_map, ss_src = seed_sequence.spawn(6)
    mopts = MeasureOptions(n_sigma=cfg.n_sigma, min_search_px=cfg.min_search_px, max_search_px=cfg.max_search_px,
                           campaign=scenario.name, run=int(run_index))
    sources = [plugins.measurement_sources.get(s.kind)(s, cfg) for s in cfg.sources]
    if cfg.methods or any(s.needs_images for s in sources):
        ts, frames, truth, maplets, ts0 = _rendered_inputs(scenario, base_dir, workdir, cfg, ss_noise, ss_map)
        L_table, _ = onboard_photometry(ts0, mopts)
        sources = [LandmarkMethodSource(make_method(n, mopts, L_table), cfg, mopts) for n in cfg.methods] + sources
    else:
        ts, (frames, truth, maplets) = None, planned_descent(scenario, base_dir, cfg)
    inp = run_inputs(ts, frames, truth, maplets, cfg, scenario, run_index, (ss_x0, ss_st, ss_acc))
    make_filter = plugins.filters.get(cfg.filter, where="descent_navigation.filter: ")   # through the contract
    frows, lrows = [], []
    for src in sources:
        src.prepare(inp, ss_src)
        f, lr = run_method(src, inp, make_filter(filter_options(cfg, truth.omega_rad_s)), cfg, mopts)
        frows += f
        lrows += lr
    return {"descent_filter": _table(frows, "reason"), "descent_landmarks": _table(lrows, "reason")}


def _table(rows: list[dict], categorical: str):
    """A pyarrow table of rows (same keys), ``categorical`` dictionary-encoded."""
    import pyarrow as pa

    if not rows:
        return pa.table({})
    keys = list(dict.fromkeys(k for r in rows for k in r))       # sources add their own constant columns
    cols = {k: [r.get(k) for r in rows] for k in keys}
    t = pa.table(cols)
    i = t.column_names.index(categorical)
    return t.set_column(i, categorical, pa.array(cols[categorical], pa.string()).dictionary_encode())
