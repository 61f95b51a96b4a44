"""Image-in-the-loop coastline navigation: rendered frames → extraction → matching → LOS → the paper's EKF.

What the paper's geometric simulation idealises and this mode does not (rendered images, clouds, a degraded onboard
database with a smooth map error, association by registration), the per-run draws and the ``coastline_frames``
table: docs/coastline_ekf.md.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from estimators.coastline.ekf import BatchCoastlineEKF, EKFOptions, nees
from estimators.coastline.extract import ExtractOptions, extract_coastline
from estimators.coastline.los import small_rotation_matrices
from estimators.coastline.match import MatchOptions, match_coastline
from renderlab.campaign.cache import cached_truthset
from renderlab.campaign.reexpose import ReexposedTruthSet
from renderlab.errors import UserError
from renderlab.files.truthset import TruthSet
from renderlab.geometry.camera import CameraModel
from renderlab.scenario import scenario_from_dict, truth_dict
from renderlab.sensor.model import SensorOptions
from renderlab.studies.coastline_ekf.config import check_perturbations
from renderlab.studies.coastline_ekf.geometric import filter_table
from renderlab.worlds.earth.coast_db import CoastDBOptions, coast_db_ecef
from renderlab.worlds.earth.plan import EarthPlan

__all__ = ["render_scenario_dict", "run_image_study"]


def render_scenario_dict(scenario) -> dict:
    """What is rendered: the scenario without its campaign-only sections, frames one cadence after the prior."""
    d = truth_dict(scenario.to_dict())
    d["trajectory"]["start_s"] = float(d["trajectory"]["start_s"]) + float(d["trajectory"]["dt_s"])
    return d


def _prior_truth(scenario) -> np.ndarray:
    """True ECI state at the prior time ``trajectory.start_s`` (the Earth world's own orbit code)."""
    d = scenario.model_copy(update={"trajectory": scenario.trajectory.model_copy(update={"frames": 1})})
    st = EarthPlan.from_scenario(d).states[0]
    return np.concatenate([st["r_eci"], st["v_eci"]])


def _draw_run(seed_sequence, K: int) -> tuple[np.ndarray, np.ndarray, list[int], int]:
    """The run's draws from one ``PCG64(seed_sequence)`` stream, in this order: initial-estimate (6,) and per-frame
    star-tracker (K, 3) standard normals, K sensor-noise seeds, the map-error seed of the onboard database."""
    rng = np.random.Generator(np.random.PCG64(seed_sequence))
    z_x0, z_att = rng.standard_normal(6), rng.standard_normal((K, 3))
    noise_seeds = rng.integers(0, 2**63 - 1, size=K)
    return z_x0, z_att, [int(v) for v in noise_seeds], int(rng.integers(0, 2**31 - 1))


def _check_image_mode(scenario) -> None:
    """Refuse what image mode cannot do (one-line UserErrors)."""
    check_perturbations(scenario.perturbations)
    if scenario.coastline.duration_s is not None:
        raise UserError("coastline.duration_s applies to mode 'geometric'; image mode renders trajectory.frames")
    if not scenario.sensor.auto_exposure:
        raise UserError("coastline image mode needs sensor.auto_exposure = true (exposure from the first frame)")


@dataclass(frozen=True)
class _ImageContext:
    """What every image of a run shares: onboard and true database (ECEF), star tracker, extraction, matching."""

    db_ecef: np.ndarray
    db_true: np.ndarray
    sig_att: float
    z_att: np.ndarray
    extract: object
    match: object
    bias_dn: float
    cloud_rejection: bool


def _image_attitudes(sc_meta: dict, sig_att: float, z_att_k: np.ndarray):
    """R_ecef_from_eci, R_ecef_from_cam and the star tracker's cam_from_eci (the true one rotated by σ_att z)."""
    from scipy.spatial.transform import Rotation

    R_ef = np.asarray(sc_meta["R_ecef_from_eci"])
    R_ecef_cam = Rotation.from_quat(sc_meta["quat_ecef_from_cam_xyzw"]).as_matrix()
    T_true = (R_ef.T @ R_ecef_cam).T                                    # cam_from_eci
    return R_ef, R_ecef_cam, small_rotation_matrices(sig_att * z_att_k) @ T_true


def _los_err_px(camera, sc_meta: dict, R_ecef_cam: np.ndarray, db_true: np.ndarray, mt) -> float:
    """Median pixel distance of the observed points to the true projection of their (error-free) database points."""
    r_ecef = np.asarray(sc_meta["r_ecef_m"])
    true_sl = camera.project((db_true[mt.db_index] - r_ecef) @ R_ecef_cam)
    return float(np.median(np.linalg.norm(mt.obs_sl - true_sl, axis=1)))


def _frame_row(k: int, t_k: float, ex, mt, m: int, los_err: float, t0: float, t1: float, t2: float) -> dict:
    """The ``coastline_frames`` row of image k (extraction ``ex``, matching ``mt``, timings t0 < t1 < t2)."""
    return {"frame": k, "t_s": t_k, "n_edge": len(ex.points), "n_edge_clean": int(ex.clean.sum()),
            "n_edge_flagged": int((~ex.clean).sum()), "n_cloud_edges": int(ex.n_cloud_edges),
            "cloud_fraction": float(np.mean(ex.labels == 2)), "n_predicted": int(mt.n_predicted),
            "n_inliers": int(mt.n_inliers), "shift_s_px": float(mt.shift_px[0]),
            "shift_l_px": float(mt.shift_px[1]), "n_matched": m, "match_ok": bool(mt.ok),
            "residual_px": float(mt.residual_px), "los_err_px_median": los_err,
            "t_extract_ms": 1e3 * (t1 - t0), "t_match_ms": 1e3 * (t2 - t1)}


def _update_with_image(fr, k: int, ekf, ctx: _ImageContext) -> tuple[dict, float, int]:
    """Extract, match and (with ≥ 1 match) update the filter with frame k → (frames row, NIS, matched points)."""
    sc_meta = fr.meta["spacecraft"]
    R_ef, R_ecef_cam, T_hat = _image_attitudes(sc_meta, ctx.sig_att, ctx.z_att[k])
    camera = CameraModel.from_dict(fr.meta["camera"])
    t0 = time.perf_counter()
    ex = extract_coastline(fr.dn.astype(np.float64) - ctx.bias_dn, ctx.extract)
    t1 = time.perf_counter()
    use = ex.clean if ctx.cloud_rejection else np.ones(len(ex.points), bool)
    db_eci = ctx.db_ecef @ R_ef                                           # R_efᵀ p for each row
    mt = match_coastline(ex.points[use], db_eci, ekf.x[0, :3], T_hat, camera, ctx.match)
    t2 = time.perf_counter()
    m = len(mt.db_index) if mt.ok else 0
    nis = np.nan
    if m:
        nis = float(ekf.update(mt.los_cam[None], db_eci[mt.db_index], T_hat[None]).nis[0])
    los_err = _los_err_px(camera, sc_meta, R_ecef_cam, ctx.db_true, mt) if m else np.nan
    return _frame_row(k, float(fr.time_s), ex, mt, m, los_err, t0, t1, t2), nis, m


def run_image_study(scenario, base_dir, run_index: int, seed_sequence, workdir) -> dict:
    """One image-in-the-loop run → ``{"coastline_filter": table, "coastline_frames": table}``."""
    import pyarrow as pa

    c = scenario.coastline
    tr, w, p = scenario.trajectory, scenario.world, scenario.perturbations
    _check_image_mode(scenario)
    truth_sc = scenario_from_dict(render_scenario_dict(scenario), "coastline image scenario")  # from the truth cache
    ts = TruthSet.open(cached_truthset(truth_sc, Path(base_dir), Path(workdir) / "truth_cache")[0])
    K = len(ts)
    bounds = tuple(json.loads((ts.path / "coast_db.json").read_text())["region_bounds_lonlat_deg"])
    z_x0, z_att, noise_seeds, map_seed = _draw_run(seed_sequence, K)      # fixed layout of draws
    map_err = w.coast_db_error_m if c.map_error_m is None else c.map_error_m
    tol, scale = float(w.coast_db_tolerance_m), float(w.coast_db_error_scale_m)
    db_ecef = coast_db_ecef(bounds, CoastDBOptions(tol, float(map_err), scale, map_seed))
    db_true = coast_db_ecef(bounds, CoastDBOptions(tol, 0.0, scale, 0))

    sd0 = np.concatenate([np.asarray(p.apriori_position_sigma_m, float), np.asarray(p.apriori_velocity_sigma_mps, float)])
    x_true0 = _prior_truth(scenario)
    sig_att = math.radians(tr.star_tracker_sigma_arcsec / 3600.0)
    # a smooth map error is a shared per-image LOS rotation of ≈ σ_map/h (docs/coastline_ekf.md)
    sig_shared = math.hypot(sig_att, map_err / (tr.altitude_km * 1e3)) if c.map_error_in_filter else sig_att
    ekf = BatchCoastlineEKF((x_true0 + sd0 * z_x0)[None], np.diag(sd0**2),
                            EKFOptions(sigma_theta_rad=c.sigma_theta_mrad * 1e-3, sigma_attitude_rad=sig_shared,
                                       q_acc_m2_s3=c.process_noise_m2_s3, max_step_s=c.filter_step_s))
    sensor_opts = SensorOptions(**scenario.sensor.options_dict())
    frames = ReexposedTruthSet(ts, sensor_opts, noise_seeds) if c.sensor_noise else ts
    mo = MatchOptions(search_px=c.search_px, gate_px=c.match_gate_px, points_per_image=c.points_per_image)
    ctx = _ImageContext(db_ecef, db_true, sig_att, z_att, ExtractOptions(), mo, sensor_opts.bias_dn,
                        c.cloud_rejection)
    # per time (the prior first): time, estimate, covariance, truth, NIS, matched LOS; per image: diagnostics
    h = {"t": [float(tr.start_s)], "x": [ekf.x[0].copy()], "P": [ekf.P[0].copy()], "x_true": [x_true0],
         "nis": [np.nan], "m": [0]}
    rows = []
    for k in range(K):
        fr = frames.load(k)
        ekf.propagate(float(fr.time_s) - h["t"][-1])
        row, nis, m = _update_with_image(fr, k, ekf, ctx)
        rows.append(row)
        sc_meta = fr.meta["spacecraft"]
        for key, v in zip(h, (float(fr.time_s), ekf.x[0].copy(), ekf.P[0].copy(),
                              np.concatenate([sc_meta["r_eci_m"], sc_meta["v_eci_mps"]]), nis, m)):
            h[key].append(v)
    xs, Ps, x_tr = np.array(h["x"]), np.array(h["P"]), np.array(h["x_true"])
    out = {"coastline_filter": filter_table(np.array(h["t"]), x_tr, [run_index], xs[None], Ps[None],
                                            np.array(h["nis"])[None], nees(xs - x_tr, Ps)[None], h["m"])}
    if rows:
        ft = pa.table({name: [r[name] for r in rows] for name in rows[0]})
        out["coastline_frames"] = ft.add_column(0, "run", pa.array([run_index] * len(rows), pa.int64()))
    return out
