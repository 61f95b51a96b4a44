r"""Geometric descents of the onboard filter with injected landmark errors (eq. N1 of docs/descent_navigation.md):
any :class:`~renderlab.contracts.error_model.LandmarkErrorModel` flown along the descent study's truth, run i paired
with run i of the rendered campaign. :func:`fly_models` (scenario, models, runs, seed) → one touchdown-proxy row per
model (and floor) and run; :func:`rendered_touchdown` → the rendered campaign's rows to validate against."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from estimators.descent_nav import pixel_covariance
from renderlab import plugins
from renderlab.campaign.plan import run_seed_sequence
from renderlab.contracts.error_model import LandmarkErrorModel
from renderlab.contracts.landmark import CameraPose
from renderlab.contracts.navigation import FilterMeasurement
from renderlab.errors import UserError
from renderlab.scenario import load_scenario
from renderlab.studies.descent_navigation.run import check, filter_options, section
from renderlab.studies.descent_navigation.run import run_draws as study_draws
from renderlab.studies.descent_navigation.sources import select_landmarks
from renderlab.studies.descent_navigation.truth import planned_descent

#: the method whose declared σ the floor's filter uses (as the rendered campaign's Retina runs)
FLOOR_FILTER_METHOD = "retina"


@dataclass(frozen=True)
class Geometry:
    """The descent the filter flies: truth, images' true poses and camera, the landmark catalog."""

    truth: object              # TrueDescent
    times: np.ndarray          # (K,)
    R_true: np.ndarray         # (K, 3, 3) body ← camera
    pos_true: np.ndarray       # (K, 3)
    camera: object             # CameraModel (every image)
    centres: np.ndarray        # (L, 3)
    spacing: np.ndarray        # (L,)
    ids: np.ndarray            # (L,) landmark ids
    R_site: np.ndarray         # body ← site (east, north, up)
    cfg: object                # DescentNavigationConfig
    campaign_seed: int


def descent_geometry(scenario_path) -> Geometry:
    """The :class:`Geometry` of a descent-navigation scenario, built without rendering (the world's plan,
    :func:`renderlab.studies.descent_navigation.truth.planned_descent`)."""
    from pathlib import Path

    scenario, base = load_scenario(Path(scenario_path))
    check(scenario)
    cfg = section(scenario)
    frames, truth, ms = planned_descent(scenario, base, cfg)
    return Geometry(truth, frames["times"], frames["R_true"], frames["pos_true"], frames["cameras"][0],
                    np.array([m.center_m for m in ms], float), np.array([m.spacing_m for m in ms], float),
                    np.array([m.landmark_id for m in ms], np.int64), frames["R_site"], cfg,
                    int(scenario.campaign.seed))


def run_draws(geom: Geometry, run: int) -> dict:
    """Run ``run``'s initial estimate, star tracker and accelerometer, drawn as the descent study draws them."""
    _, ss_x0, ss_st, ss_acc = run_seed_sequence(geom.campaign_seed, run).spawn(4)
    return study_draws(geom.truth, geom.times, geom.R_true, geom.cfg, (ss_x0, ss_st, ss_acc))


def landmark_draws(geom: Geometry, seed: int, run: int) -> tuple[np.ndarray, np.ndarray]:
    """(β (L, 2), ε (K, L, 2)) of eq. N1 for run ``run``: standard normals, shared by every configuration."""
    rng = np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(int(run),)))
    return rng.standard_normal((len(geom.ids), 2)), rng.standard_normal((len(geom.times), len(geom.ids), 2))


def fly(geom: Geometry, draws: dict, model: LandmarkErrorModel | None, beta: np.ndarray, eps: np.ndarray,
        method: str) -> dict:
    """One descent of the filter with eq. N1's measurements (``model`` None: no landmark error) → the
    touchdown-proxy row: error and 1σ at the last image (site east, north, up), NEES there, ANEES over the
    images, landmarks kept, track loss (``track_loss_frames`` images in a row without a kept landmark)."""
    cfg, cam = geom.cfg, geom.camera
    filt = plugins.filters.get("descent_ekf")(filter_options(cfg, geom.truth.omega_rad_s))
    filt.initialize(float(geom.times[0]), draws["x0"], draws["P0"])
    sig_px = cfg.sigma_for(method)
    nees, kept_total, misses, lost, diverged = [], 0, 0, False, False
    for k, t in enumerate(geom.times):
        for _t0, t1, u in draws["accel"][k]:
            filt.set_input(u)
            filt.propagate(t1)
        x = filt.x
        R_st = draws["R_star"][k]
        sel = select_landmarks(cam, CameraPose(R_st, x[:3]), geom.centres, geom.spacing, cfg)
        xc = CameraPose(geom.R_true[k], geom.pos_true[k]).to_camera(geom.centres[sel])
        true_px = cam.project(xc)
        sel, xc, true_px = sel[cam.in_image(true_px)], xc[cam.in_image(true_px)], true_px[cam.in_image(true_px)]
        kept = 0
        if sel.size:
            z = true_px.copy()
            if model is not None:
                mu, sb, sn = model.at(xc[:, 2], cam.fx)
                z += mu + sb * beta[sel] + sn * eps[k, sel]
            pts = geom.centres[sel]
            gsd = ((pts - x[:3]) @ R_st)[:, 2] / cam.fx
            sg = cfg.ground_sigma_for(method)
            sig = np.sqrt(sig_px ** 2 + (sg / gsd) ** 2) if sg > 0 else sig_px
            R = pixel_covariance(cam, pts, x[:3], R_st, sig, draws["sigma_st"])
            meas = FilterMeasurement("pixel", z.reshape(-1), R, {"points_body_m": pts, "R_body_from_cam": R_st,
                                                                  "camera": cam, "flagged": np.zeros(len(sel), bool)})
            try:
                filt.update(float(t), meas)
                kept = int(filt.last.kept.sum())
            except UserError:
                diverged = True
                break
        kept_total += kept
        misses = misses + 1 if kept == 0 else 0
        lost = lost or misses >= cfg.track_loss_frames
        d = filt.x[:6] - geom.truth.state(t)
        nees.append(float(d @ np.linalg.solve(filt.P[:6, :6], d)))
    return _touchdown(geom, filt, nees, kept_total, lost, diverged)


def _touchdown(geom, filt, nees, kept_total, lost, diverged) -> dict:
    nan = float("nan")
    out = {"track_lost": bool(lost or diverged), "diverged": bool(diverged), "n_kept": int(kept_total)}
    if diverged:
        return {**out, **{f"{p}_{a}_m": nan for p in ("err", "sig") for a in "enu"}, "err_norm_m": nan,
                "nees_td": nan, "anees": nan}
    e = geom.R_site.T @ (filt.x[:3] - geom.truth.position(geom.times[-1]))
    sig = np.sqrt(np.diag(geom.R_site.T @ filt.P[:3, :3] @ geom.R_site))
    return {**out, **{f"err_{a}_m": float(v) for a, v in zip("enu", e)},
            **{f"sig_{a}_m": float(v) for a, v in zip("enu", sig)}, "err_norm_m": float(np.linalg.norm(e)),
            "nees_td": nees[-1], "anees": float(np.mean(nees))}


_WORKER: dict = {}


def _init_worker(scenario_path: str, models: list) -> None:
    _WORKER["geom"], _WORKER["models"] = descent_geometry(scenario_path), models


def _injected(model: LandmarkErrorModel | None, fx: float, depth_m: float) -> dict:
    """eq. N1's μ, σ_b, σ_n (px, per axis) at depth ``depth_m`` (the last image's), for the table."""
    if model is None:
        return {f"inj_{q}_{a}_px": 0.0 for q in ("mu", "sd_bias", "sd_noise") for a in "sl"}
    vals = model.at(np.array([depth_m]), fx)
    return {f"inj_{q}_{a}_px": float(v[0, j]) for q, v in zip(("mu", "sd_bias", "sd_noise"), vals)
            for j, a in enumerate("sl")}


def _fly_run(args) -> list[dict]:
    """Worker: every model of run ``run`` (and, with ``floor`` labels, the descent without landmark error) → rows."""
    run, seed, floor = args
    geom, models = _WORKER["geom"], _WORKER["models"]
    draws = run_draws(geom, run)
    beta, eps = landmark_draws(geom, seed, run)
    depth = float(np.linalg.norm(geom.pos_true[-1] - geom.truth.origin_m))
    rows = [{"mapping": "", "config": floor[0], "method": floor[1], "run": run,
             **_injected(None, geom.camera.fx, depth),
             **fly(geom, draws, None, beta, eps, FLOOR_FILTER_METHOD)}] if floor else []
    for m in models:
        rows.append({"mapping": m.mapping, "config": m.config, "method": m.method, "run": run,
                     **_injected(m, geom.camera.fx, depth), **fly(geom, draws, m, beta, eps, m.method)})
    return rows


def fly_models(scenario_path, models: list, runs: int, seed: int, workers: int = 2, floor: tuple | None = None):
    """Every model of ``models`` (:class:`~renderlab.contracts.error_model.LandmarkErrorModel`) flown in runs
    0..``runs``-1 along ``scenario_path``'s descent → a pyarrow table (module docstring; progress on stderr).
    ``floor``: (config, method) labels of one more descent per run without landmark error (mapping ``""``)."""
    import concurrent.futures as cf
    import sys
    import time

    import pyarrow as pa

    bad = [type(m).__name__ for m in models if not isinstance(m, LandmarkErrorModel)]
    if bad:
        raise TypeError(f"fly_models: {bad[0]} is not a LandmarkErrorModel (config, method, mapping, at())")
    rows, t0 = [], time.perf_counter()
    with cf.ProcessPoolExecutor(max_workers=max(1, workers), initializer=_init_worker,
                                initargs=(str(scenario_path), models)) as pool:
        for i, r in enumerate(pool.map(_fly_run, [(run, seed, floor) for run in range(runs)])):
            rows += r
            if (i + 1) % 10 == 0 or i + 1 == runs:
                print(f"[{i + 1}/{runs}] runs flown ({len(r)} descents each, "
                      f"{time.perf_counter() - t0:.0f} s)", file=sys.stderr, flush=True)
    return pa.table({k: [r[k] for r in rows] for k in rows[0]})


def rendered_touchdown(scenario_path):
    """The rendered campaign's touchdown rows (last image) from ``<scenario folder>/tables/descent_filter.parquet``:
    run, method, error and 1σ (east, north, up), NEES, track loss."""
    from pathlib import Path

    import pyarrow.compute as pc
    import pyarrow.parquet as pq

    p = Path(scenario_path).parent / "tables" / "descent_filter.parquet"
    if not p.is_file():
        raise UserError(f"navigation budget: no rendered campaign table {p} beside the scenario")
    t = pq.read_table(p)
    last = pc.max(t.column("frame")).as_py()
    t = t.filter(pc.equal(t.column("frame"), last))
    keep = ["run", "method", "frame", "t_s", "err_e_m", "err_n_m", "err_u_m", "sig_e_m", "sig_n_m", "sig_u_m",
            "nees", "track_lost", "n_kept"]
    return t.select(keep)
