r"""Image-in-the-loop coastline navigation: rendered frames → extraction → matching → LOS → the paper's EKF.

What the paper's geometric simulation (Straub & Christian, Section III) idealises and this mode does not:
the coastline points are found in a rendered sensor image (finite resolution, blur, shot/read noise;
:mod:`estimators.coastline.extract`), clouds hide and fake edges, the onboard database is a degraded GSHHG copy
(simplified, displaced by a smooth map error correlated over ~100 km, so the errors of the points of one image
are *not* independent as eq. 18 assumes), and points are associated by registering the database projected with
the a-priori state (:mod:`estimators.coastline.match`) — no identity is given.

Truth: the scenario's Earth world and LEO trajectory rendered once (through the campaign's truth cache,
shared by every run): the filter's prior is at ``trajectory.start_s`` and the frames are taken at
``start_s + (k + 1)·dt_s``, k = 0..frames−1 (the geometric mode's convention). Per run (one ``SeedSequence``,
draws in a fixed layout): the initial estimate (``perturbations.apriori_*``), the star-tracker attitude noise,
the sensor noise (the cached radiance is re-exposed, ``coastline.sensor_noise``) and the map-error realisation
of the onboard database (``coastline.map_error_m``, default ``world.coast_db_error_m``).

Tables: ``coastline_filter`` (the geometric mode's columns) and ``coastline_frames``: per image the extracted
edge points (clean / flagged), rejected cloud edges, registration shift and inliers, matched points, the median
pixel distance of the observed points to the true projection of their database points (``los_err_px_median``,
which includes the map error) and the timings.
"""

from __future__ import annotations

import functools
import json
import math
import time
from pathlib import Path

import numpy as np

from renderlab.errors import UserError

__all__ = ["render_scenario_dict", "run_image_study"]


def render_scenario_dict(scenario) -> dict:
    """What is rendered: the scenario without its campaign-only sections, frames one cadence after the prior."""
    d = json.loads(json.dumps(scenario.to_dict()))
    for key in ("perturbations", "campaign", "coastline"):
        d.pop(key, None)
    d["trajectory"]["start_s"] = float(d["trajectory"]["start_s"]) + float(d["trajectory"]["dt_s"])
    return d


@functools.lru_cache(maxsize=4)
def _database(bounds: tuple, tolerance_m: float, error_m: float, scale_m: float, seed: int) -> np.ndarray:
    """Onboard database ECEF points (n, 3) of one map-error realisation over a lon/lat box."""
    import shapely

    from renderlab.worlds.earth.coast_db import CoastDBOptions, build_coast_db
    from renderlab.worlds.earth.gshhg import load_gshhg

    cols = build_coast_db(load_gshhg(), shapely.box(*bounds), CoastDBOptions(tolerance_m, error_m, scale_m, seed))
    return np.stack([cols["x_ecef_m"], cols["y_ecef_m"], cols["z_ecef_m"]], -1)


def _prior_truth(scenario) -> np.ndarray:
    """True ECI state at the prior time ``trajectory.start_s`` (the Earth world's own orbit code)."""
    from renderlab.worlds.earth.plan import EarthPlan

    d = scenario.model_copy(update={"trajectory": scenario.trajectory.model_copy(update={"frames": 1})})
    st = EarthPlan.from_scenario(d).states[0]
    return np.concatenate([st["r_eci"], st["v_eci"]])


def run_image_study(scenario, base_dir, run_index: int, seed_sequence, workdir) -> dict:
    """One image-in-the-loop run → ``{"coastline_filter": table, "coastline_frames": table}``."""
    import dataclasses

    import pyarrow as pa
    from scipy.spatial.transform import Rotation

    from estimators.coastline.ekf import BatchCoastlineEKF, EKFOptions, nees
    from estimators.coastline.extract import ExtractOptions, extract_coastline
    from estimators.coastline.los import small_rotation_matrices
    from estimators.coastline.match import MatchOptions, match_coastline
    from renderlab.campaign.cache import cached_truthset
    from renderlab.geometry.camera import CameraModel
    from renderlab.scenario import scenario_from_dict
    from renderlab.sensor import SensorOptions, expose
    from renderlab.studies.coastline_ekf.geometric import FILTER_COLUMNS, filter_status, ric_axes
    from renderlab.studies.coastline_ekf.config import check_perturbations
    from renderlab.truthset import TruthSet

    c = scenario.coastline
    tr, w, p = scenario.trajectory, scenario.world, scenario.perturbations
    check_perturbations(p)
    if c.duration_s is not None:
        raise UserError("coastline.duration_s applies to mode 'geometric'; image mode renders trajectory.frames")
    if not scenario.sensor.auto_exposure:
        raise UserError("coastline image mode needs sensor.auto_exposure = true (exposure from the first frame)")
    truth_sc = scenario_from_dict(render_scenario_dict(scenario), "coastline image scenario")
    path, _ = cached_truthset(truth_sc, Path(base_dir), Path(workdir) / "truth_cache")
    ts = TruthSet.open(path)
    K = len(ts)
    bounds = tuple(json.loads((ts.path / "coast_db.json").read_text())["region_bounds_lonlat_deg"])

    rng = np.random.Generator(np.random.PCG64(seed_sequence))            # fixed layout of draws
    z_x0, z_att = rng.standard_normal(6), rng.standard_normal((K, 3))
    noise_seeds = rng.integers(0, 2**63 - 1, size=K)
    map_seed = int(rng.integers(0, 2**31 - 1))
    map_err = w.coast_db_error_m if c.map_error_m is None else c.map_error_m
    db_ecef = _database(bounds, float(w.coast_db_tolerance_m), float(map_err), float(w.coast_db_error_scale_m),
                        map_seed)
    db_true = _database(bounds, float(w.coast_db_tolerance_m), 0.0, float(w.coast_db_error_scale_m), 0)

    sd0 = np.concatenate([np.asarray(p.apriori_position_sigma_m, float), np.asarray(p.apriori_velocity_sigma_mps, float)])
    x_true0 = _prior_truth(scenario)
    sig_att = math.radians(tr.star_tracker_sigma_arcsec / 3600.0)
    # a map error that is smooth over the footprint displaces every point of an image alike: seen from the
    # altitude h it is a shared LOS rotation of ≈ σ_map/h, the same form as the star-tracker term of R
    sig_shared = math.hypot(sig_att, map_err / (tr.altitude_km * 1e3)) if c.map_error_in_filter else sig_att
    ekf = BatchCoastlineEKF((x_true0 + sd0 * z_x0)[None], np.diag(sd0**2),
                            EKFOptions(sigma_theta_rad=c.sigma_theta_mrad * 1e-3, sigma_attitude_rad=sig_shared,
                                       q_acc_m2_s3=c.process_noise_m2_s3, max_step_s=c.filter_step_s))
    sensor_opts = SensorOptions(**scenario.sensor.options_dict())
    xo = ExtractOptions()
    mo = MatchOptions(search_px=c.search_px, gate_px=c.match_gate_px, points_per_image=c.points_per_image)
    t_prev = float(tr.start_s)
    xs, Ps, x_tr = [ekf.x[0].copy()], [ekf.P[0].copy()], [x_true0]
    ts_s, nis_l, nm_l, frames = [t_prev], [np.nan], [0], []
    for k in range(K):
        fr = ts.load(k)
        meta, sc_meta = fr.meta, fr.meta["spacecraft"]
        t_k = float(fr.time_s)
        ekf.propagate(t_k - t_prev)
        t_prev = t_k
        R_ef = np.asarray(sc_meta["R_ecef_from_eci"])
        R_ecef_cam = Rotation.from_quat(sc_meta["quat_ecef_from_cam_xyzw"]).as_matrix()
        T_true = (R_ef.T @ R_ecef_cam).T                                    # cam_from_eci
        T_hat = small_rotation_matrices(sig_att * z_att[k]) @ T_true
        camera = CameraModel.from_dict(meta["camera"])
        opts = dataclasses.replace(sensor_opts, exposure_s=float(meta["sensor"]["exposure_s"]))
        dn = expose(fr.radiance, opts, np.random.default_rng(int(noise_seeds[k]))).dn if c.sensor_noise else fr.dn
        t0 = time.perf_counter()
        ex = extract_coastline(dn.astype(np.float64) - opts.bias_dn, xo)
        t1 = time.perf_counter()
        use = ex.clean if c.cloud_rejection else np.ones(len(ex.points), bool)
        db_eci = db_ecef @ R_ef                                               # R_efᵀ p for each row
        mt = match_coastline(ex.points[use], db_eci, ekf.x[0, :3], T_hat, camera, mo)
        t2 = time.perf_counter()
        m = len(mt.db_index) if mt.ok else 0
        nis = np.nan
        if m:
            nis = float(ekf.update(mt.los_cam[None], db_eci[mt.db_index], T_hat[None]).nis[0])
        los_err = np.nan
        if m:
            r_ecef = np.asarray(sc_meta["r_ecef_m"])
            true_sl = camera.project((db_true[mt.db_index] - r_ecef) @ R_ecef_cam)
            los_err = float(np.median(np.linalg.norm(mt.obs_sl - true_sl, axis=1)))
        frames.append({"frame": k, "t_s": t_k, "n_edge": len(ex.points), "n_edge_clean": int(ex.clean.sum()),
                       "n_edge_flagged": int((~ex.clean).sum()), "n_cloud_edges": int(ex.n_cloud_edges),
                       "cloud_fraction": float(np.mean(ex.labels == 2)), "n_predicted": int(mt.n_predicted),
                       "n_inliers": int(mt.n_inliers), "shift_s_px": float(mt.shift_px[0]),
                       "shift_l_px": float(mt.shift_px[1]), "n_matched": m, "match_ok": bool(mt.ok),
                       "residual_px": float(mt.residual_px), "los_err_px_median": los_err,
                       "t_extract_ms": 1e3 * (t1 - t0), "t_match_ms": 1e3 * (t2 - t1)})
        xs.append(ekf.x[0].copy())
        Ps.append(ekf.P[0].copy())
        x_tr.append(np.concatenate([sc_meta["r_eci_m"], sc_meta["v_eci_mps"]]))
        ts_s.append(t_k)
        nis_l.append(nis)
        nm_l.append(m)
    xs, Ps, x_tr = np.array(xs), np.array(Ps), np.array(x_tr)
    err = xs - x_tr
    C = ric_axes(x_tr)
    e_r, e_v = np.einsum("kij,kj->ki", C, err[:, :3]), np.einsum("kij,kj->ki", C, err[:, 3:])
    s_r = np.sqrt(np.einsum("kij,kjl,kil->ki", C, Ps[:, :3, :3], C))
    s_v = np.sqrt(np.einsum("kij,kjl,kil->ki", C, Ps[:, 3:, 3:], C))
    vals = np.concatenate([e_r, e_v, s_r, s_v], 1)
    cols = {"run": np.full(len(ts_s), run_index, np.int64), "t_s": np.array(ts_s)}
    for j, name in enumerate(FILTER_COLUMNS[2:14]):
        cols[name] = vals[:, j]
    cols.update(nees=nees(err, Ps), nis=np.array(nis_l), n_meas=np.array(nm_l, np.int32))
    cols.update(filter_status(cols["n_meas"], np.arange(len(ts_s)) == 0))
    ft = pa.table({k: [r[k] for r in frames] for k in frames[0]}) if frames else None
    if ft is not None:
        ft = ft.add_column(0, "run", pa.array([run_index] * len(frames), pa.int64()))
    return {"coastline_filter": pa.table(cols), **({"coastline_frames": ft} if ft is not None else {})}
