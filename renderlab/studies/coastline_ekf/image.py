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
from dataclasses import dataclass, field
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
from renderlab.scenario import scenario_from_dict
from renderlab.sensor.model import SensorOptions
from renderlab.studies.coastline_ekf.config import check_perturbations
from renderlab.studies.coastline_ekf.geometric import FILTER_COLUMNS, filter_status, ric_axes
from renderlab.worlds.earth.coast_db import CoastDBOptions, build_coast_db
from renderlab.worlds.earth.gshhg import load_gshhg
from renderlab.worlds.earth.plan import EarthPlan

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


    cols = build_coast_db(load_gshhg(), shapely.box(*bounds), CoastDBOptions(tolerance_m, error_m, scale_m, seed))
    return np.stack([cols["x_ecef_m"], cols["y_ecef_m"], cols["z_ecef_m"]], -1)


def _prior_truth(scenario) -> np.ndarray:
    """True ECI state at the prior time ``trajectory.start_s`` (the Earth world's own orbit code)."""
    d = scenario.model_copy(update={"trajectory": scenario.trajectory.model_copy(update={"frames": 1})})
    st = EarthPlan.from_scenario(d).states[0]
    return np.concatenate([st["r_eci"], st["v_eci"]])


@dataclass(frozen=True)
class _RunDraws:
    """All random numbers of one run, in the fixed layout of its generator (:func:`_draw_run`)."""

    z_x0: np.ndarray          # (6,) initial-estimate standard normals
    z_att: np.ndarray         # (K, 3) star-tracker attitude standard normals, per frame
    noise_seeds: list[int]    # (K,) sensor-noise seed per frame
    map_seed: int             # map-error realisation of the onboard database


def _draw_run(seed_sequence, K: int) -> _RunDraws:
    """The run's draws from one ``PCG64(seed_sequence)`` stream: x0 (6), attitude (K, 3), K noise seeds, map seed."""
    rng = np.random.Generator(np.random.PCG64(seed_sequence))
    z_x0, z_att = rng.standard_normal(6), rng.standard_normal((K, 3))
    noise_seeds = rng.integers(0, 2**63 - 1, size=K)
    map_seed = int(rng.integers(0, 2**31 - 1))
    return _RunDraws(z_x0, z_att, [int(v) for v in noise_seeds], map_seed)


def _check_image_mode(scenario) -> None:
    """Refuse what image mode cannot do (one-line UserErrors)."""
    check_perturbations(scenario.perturbations)
    if scenario.coastline.duration_s is not None:
        raise UserError("coastline.duration_s applies to mode 'geometric'; image mode renders trajectory.frames")
    if not scenario.sensor.auto_exposure:
        raise UserError("coastline image mode needs sensor.auto_exposure = true (exposure from the first frame)")


def _truth_set(scenario, base_dir, workdir):
    """The run's truth render (:func:`render_scenario_dict`) from the campaign's truth cache."""
    truth_sc = scenario_from_dict(render_scenario_dict(scenario), "coastline image scenario")
    path, _ = cached_truthset(truth_sc, Path(base_dir), Path(workdir) / "truth_cache")
    return TruthSet.open(path)


@dataclass(frozen=True)
class _ImageContext:
    """What every image of a run shares: onboard and true database (ECEF, (n, 3)), star-tracker σ and draws,
    extraction and matching options, the sensor bias and whether flagged (cloud) edges are dropped."""

    db_ecef: np.ndarray
    db_true: np.ndarray
    sig_att: float
    z_att: np.ndarray
    extract: object
    match: object
    bias_dn: float
    cloud_rejection: bool


@dataclass
class _History:
    """Per time (the prior first): estimate, covariance, truth, NIS, matched points; per image: diagnostics."""

    t_s: list
    x: list
    P: list
    x_true: list
    nis: list = field(default_factory=lambda: [np.nan])
    n_meas: list = field(default_factory=lambda: [0])
    frames: list = field(default_factory=list)

    def append(self, ekf, x_true, t_s: float, nis: float, n_meas: int) -> None:
        self.x.append(ekf.x[0].copy())
        self.P.append(ekf.P[0].copy())
        self.x_true.append(x_true)
        self.t_s.append(t_s)
        self.nis.append(nis)
        self.n_meas.append(n_meas)


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


def _filter_table(h: _History, run_index: int):
    """The ``coastline_filter`` table (the geometric mode's columns) of a run's history."""
    import pyarrow as pa


    xs, Ps, x_tr = np.array(h.x), np.array(h.P), np.array(h.x_true)
    err = xs - x_tr
    C = ric_axes(x_tr)
    e_r, e_v = np.einsum("kij,kj->ki", C, err[:, :3]), np.einsum("kij,kj->ki", C, err[:, 3:])
    s_r = np.sqrt(np.einsum("kij,kjl,kil->ki", C, Ps[:, :3, :3], C))
    s_v = np.sqrt(np.einsum("kij,kjl,kil->ki", C, Ps[:, 3:, 3:], C))
    vals = np.concatenate([e_r, e_v, s_r, s_v], 1)
    cols = {"run": np.full(len(h.t_s), run_index, np.int64), "t_s": np.array(h.t_s)}
    for j, name in enumerate(FILTER_COLUMNS[2:14]):
        cols[name] = vals[:, j]
    cols.update(nees=nees(err, Ps), nis=np.array(h.nis), n_meas=np.array(h.n_meas, np.int32))
    cols.update(filter_status(cols["n_meas"], np.arange(len(h.t_s)) == 0))
    return pa.table(cols)


def run_image_study(scenario, base_dir, run_index: int, seed_sequence, workdir) -> dict:
    """One image-in-the-loop run → ``{"coastline_filter": table, "coastline_frames": table}``."""
    import pyarrow as pa


    c = scenario.coastline
    tr, w, p = scenario.trajectory, scenario.world, scenario.perturbations
    _check_image_mode(scenario)
    ts = _truth_set(scenario, base_dir, workdir)
    K = len(ts)
    bounds = tuple(json.loads((ts.path / "coast_db.json").read_text())["region_bounds_lonlat_deg"])
    draws = _draw_run(seed_sequence, K)                                   # fixed layout of draws
    map_err = w.coast_db_error_m if c.map_error_m is None else c.map_error_m
    db_ecef = _database(bounds, float(w.coast_db_tolerance_m), float(map_err), float(w.coast_db_error_scale_m),
                        draws.map_seed)
    db_true = _database(bounds, float(w.coast_db_tolerance_m), 0.0, float(w.coast_db_error_scale_m), 0)

    sd0 = np.concatenate([np.asarray(p.apriori_position_sigma_m, float), np.asarray(p.apriori_velocity_sigma_mps, float)])
    x_true0 = _prior_truth(scenario)
    sig_att = math.radians(tr.star_tracker_sigma_arcsec / 3600.0)
    # a map error that is smooth over the footprint displaces every point of an image alike: seen from the
    # altitude h it is a shared LOS rotation of ≈ σ_map/h, the same form as the star-tracker term of R
    sig_shared = math.hypot(sig_att, map_err / (tr.altitude_km * 1e3)) if c.map_error_in_filter else sig_att
    ekf = BatchCoastlineEKF((x_true0 + sd0 * draws.z_x0)[None], np.diag(sd0**2),
                            EKFOptions(sigma_theta_rad=c.sigma_theta_mrad * 1e-3, sigma_attitude_rad=sig_shared,
                                       q_acc_m2_s3=c.process_noise_m2_s3, max_step_s=c.filter_step_s))
    sensor_opts = SensorOptions(**scenario.sensor.options_dict())
    frames = ReexposedTruthSet(ts, sensor_opts, draws.noise_seeds) if c.sensor_noise else ts
    mo = MatchOptions(search_px=c.search_px, gate_px=c.match_gate_px, points_per_image=c.points_per_image)
    ctx = _ImageContext(db_ecef, db_true, sig_att, draws.z_att, ExtractOptions(), mo, sensor_opts.bias_dn,
                        c.cloud_rejection)
    t_prev = float(tr.start_s)
    h = _History([t_prev], [ekf.x[0].copy()], [ekf.P[0].copy()], [x_true0])
    for k in range(K):
        fr = frames.load(k)
        t_k = float(fr.time_s)
        ekf.propagate(t_k - t_prev)
        t_prev = t_k
        row, nis, m = _update_with_image(fr, k, ekf, ctx)
        h.frames.append(row)
        sc_meta = fr.meta["spacecraft"]
        h.append(ekf, np.concatenate([sc_meta["r_eci_m"], sc_meta["v_eci_mps"]]), t_k, nis, m)
    out = {"coastline_filter": _filter_table(h, run_index)}
    if h.frames:
        ft = pa.table({name: [r[name] for r in h.frames] for name in h.frames[0]})
        out["coastline_frames"] = ft.add_column(0, "run", pa.array([run_index] * len(h.frames), pa.int64()))
    return out
