"""The unknown-satellite study, one sequence: truth set → stage 1 → stage 2 → scores against the truth
(:func:`analyse_truthset`; a campaign run calls it with its own seed). The a-priori guess, the monocular scale and
the gauge-free scores: docs/unknown_satellite.md."""

from __future__ import annotations

from collections import namedtuple
from dataclasses import dataclass, field

import numpy as np

from estimators.pose import (
    DetectOptions,
    EstimationError,
    Stage1Options,
    Stage1Problem,
    Stage2Options,
    TrackOptions,
    build_database,
    detect_points,
    observability,
    run_stage2,
    track_points,
    with_full_inertia,
)
from estimators.pose.gauge import gauge_free
from estimators.pose.onboard_model import exp_so3, log_so3
from estimators.pose.rigidity import solve_rigid
from estimators.pose.stage2 import FLAG_NAMES
from renderlab.errors import UserError
from renderlab.files.truthset import TruthSet
from renderlab.geometry.camera import CameraModel


@dataclass(frozen=True)
class PriorOptions:
    """1σ of the seeded a-priori errors (r0, v0 per LVLH axis: a float or three floats)."""

    sigma_r0_m: float | tuple[float, float, float] = 0.05
    sigma_v0_mps: float | tuple[float, float, float] = 0.02
    sigma_att_deg: float = 5.0
    sigma_w_deg_s: float = 0.5
    sigma_ratio_frac: float = 0.1
    range_sigma_m: float = 0.05


@dataclass(frozen=True)
class StudyOptions:
    prior: PriorOptions = PriorOptions()
    sigma_px: float = 0.3
    epsilon_px: float = 12.0
    min_track_frames: int = 5
    max_nfev: int = 300
    match_px: float = 3.0                # track ↔ truth feature association for scoring


@dataclass
class SequenceResult:
    tables: dict                         # name → pyarrow.Table
    summary: dict
    observability: list[str] = field(default_factory=list)
    stage1: object = None
    stage2: object = None
    problem: object = None               # the stage-1 problem on the kept (rigid) tracks
    gauge_free: object = None            # estimators.pose.gauge.GaugeFree at the stage-1 solution


def _rot(q):
    from scipy.spatial.transform import Rotation

    return Rotation.from_quat(q).as_matrix()


def _inertia_lvlh(R_lvlh_from_body, inertia):
    """Trace-normalised inertia tensor in LVLH (gauge-free: independent of the principal axes' labels)."""
    T = R_lvlh_from_body @ np.diag(inertia) @ R_lvlh_from_body.T
    return T / np.trace(T)


def axis_relabelling(R_est0: np.ndarray, R_true0: np.ndarray) -> np.ndarray:
    """The proper signed permutation P (one of the 24 of the octahedral group) for which ``R_est0 Pᵀ`` is closest to
    ``R_true0``: which principal axis is called 1, 2 or 3 (and its sign) is a discrete gauge, relabelled axes give
    the same images. Truth-labelled body vectors are then ``P x_est`` and the moments ``|P| I_est``."""
    from scipy.spatial.transform import Rotation

    perms = np.rint(Rotation.create_group("O").as_matrix()) + 0.0  # exact entries, no −0
    return perms[int(np.argmin([np.linalg.norm(log_so3((R_est0 @ P.T).T @ R_true0)) for P in perms]))]


def _match_tracks(tracks_db, db, ft, max_px):
    """Truth feature id of each database point (−1 if none within ``max_px`` on average)."""
    import collections

    truth = collections.defaultdict(dict)
    for f, j, s, l in zip(ft["frame"], ft["feature_id"], ft["s"], ft["l"]):
        truth[j][f] = (s, l)
    out = []
    for k in range(db.n_points):
        m = db.point == k
        best, best_d = -1, max_px
        for j, tj in truth.items():
            d = [np.hypot(*(np.asarray(tj[f]) - z)) for f, z in zip(db.frame[m], db.sl[m]) if f in tj]
            d = [x for x in d if np.isfinite(x)]
            if len(d) == m.sum() and np.mean(d) < best_d:
                best, best_d = j, float(np.mean(d))
        out.append(best)
    return np.array(out)


#: what the truth set fixes for the estimators: camera, R_lvlh_from_cam, camera offset (LVLH), mean motion, times
_Sequence = namedtuple("_Sequence", "camera R_lc d n times")
#: per-frame truth ``tr`` (r, v, q, ω), inertia, ratios I1/I3, I2/I3, attitude at the epoch (R0) and per frame (R)
_Truth = namedtuple("_Truth", "tr inertia ratios R0 R")


def _truth(recs: list) -> _Truth:
    tr = {k: np.array([r["microsat"][k] for r in recs]) for k in
          ("r_lvlh_m", "v_lvlh_mps", "quat_lvlh_from_body_xyzw", "omega_body_rad_s")}
    I_true = np.asarray(recs[0]["microsat"]["inertia_kg_m2"])
    return _Truth(tr, I_true, I_true[:2] / I_true[2], _rot(tr["quat_lvlh_from_body_xyzw"][0]),
                  np.array([_rot(q) for q in tr["quat_lvlh_from_body_xyzw"]]))


def _apriori(t: _Truth, d: np.ndarray, p: PriorOptions, rng: np.random.Generator) -> tuple:
    """The seeded a-priori guess (R_ref, r0, v0, ω0, ratios, range prior), drawn in this order."""
    R_ref = t.R0 @ exp_so3(rng.normal(0, np.radians(p.sigma_att_deg), 3))
    r0g = t.tr["r_lvlh_m"][0] + rng.normal(0, p.sigma_r0_m, 3)
    v0g = t.tr["v_lvlh_mps"][0] + rng.normal(0, p.sigma_v0_mps, 3)
    w0g = t.tr["omega_body_rad_s"][0] + rng.normal(0, np.radians(p.sigma_w_deg_s), 3)
    ratios_g = t.ratios * (1 + rng.normal(0, p.sigma_ratio_frac, 2))
    range_prior = float(np.linalg.norm(t.tr["r_lvlh_m"][0] - d) + rng.normal(0, p.range_sigma_m))
    return R_ref, r0g, v0g, w0g, ratios_g, range_prior


def _solve_stage1(sq: _Sequence, db, apriori: tuple, opts: StudyOptions, ts_path):
    """Stage 1 (range prior, rigidity test, solve) from the a-priori guess → (solution, problem, rigidity result)."""
    R_ref, r0g, v0g, w0g, ratios_g, range_prior = apriori
    s1opts = Stage1Options(sigma_px=opts.sigma_px, range_prior_sigma_m=opts.prior.range_sigma_m, max_nfev=opts.max_nfev)
    try:
        problem = Stage1Problem(sq.camera, sq.R_lc, sq.d, sq.n, sq.times, db, R_ref, range_prior, s1opts)
    except EstimationError as exc:
        raise UserError(f"{ts_path}: {exc}") from None
    if db.frame.min() != 0:
        raise UserError(f"{ts_path}: no reference point tracked from the first frame")
    try:
        return solve_rigid(problem, r0g, v0g, w0g, ratios_g)
    except EstimationError as exc:   # fewer than 4 rigid tracks, or none at the epoch
        raise UserError(f"{ts_path}: {exc}") from None


def _point_rows(s1, db, fid, truth_pts, gf, t: _Truth, run: int):
    """Stage-1 ``points`` columns, the body-frame errors (M, 3), shape errors and whether ≥ 3 points matched."""
    npts = db.n_points
    sig_p = s1.sigma_theta[14:].reshape(-1, 3)
    pt_rows = {"run": [run] * npts, "method": ["stage1"] * npts, "item": db.track_ids.tolist(),
               "feature_id": fid.tolist()}
    err = np.array([s1.points_body[k] - truth_pts[j] if j >= 0 else np.full(3, np.nan) for k, j in enumerate(fid)])
    for a, ax in enumerate("xyz"):
        pt_rows[f"est_{ax}_m"] = s1.points_body[:, a].tolist()
        pt_rows[f"err_{ax}_m"] = err[:, a].tolist()
        pt_rows[f"sig_{ax}_m"] = sig_p[:, a].tolist()
    pt_rows["err_m"] = np.linalg.norm(err, axis=1).tolist()
    shape_err = np.full(npts, np.nan)
    if ok_any := (fid >= 0).sum() >= 3:  # shape error: after the best rotation about the CM (Kabsch)
        m = fid >= 0
        A, B = s1.points_body[m], truth_pts[fid[m]]
        U, _, Vt = np.linalg.svd(B.T @ A)
        C = U @ np.diag([1, 1, np.linalg.det(U @ Vt)]) @ Vt
        shape_err[m] = np.linalg.norm(A @ C.T - B, axis=1)
    pt_rows["shape_err_m"] = shape_err.tolist()
    # gauge-free: the point in LVLH at the epoch, error and CRLB σ (estimators.pose.gauge)
    q_true = np.array([t.tr["r_lvlh_m"][0] + t.R0 @ truth_pts[j] if j >= 0 else np.full(3, np.nan) for j in fid])
    pt_rows["lvlh_err_m"] = np.linalg.norm(gf.points_lvlh - q_true, axis=1).tolist()
    pt_rows["lvlh_sig_m"] = np.linalg.norm(gf.points_sigma, axis=1).tolist()
    return pt_rows, err, shape_err, ok_any


def _history_rows(s1, problem, fid, truth_pts, t: _Truth, run: int):
    """``stage1_history`` rows: the errors of every stage-1 iterate (Figs 5-7)."""
    tr, I_true, ratios_true = t.tr, t.inertia, t.ratios
    hist_rows = []
    for it, th in enumerate(s1.history):
        r0, v0, dphi, w0, inertia, pts = problem.unpack(th)
        e_p = [np.linalg.norm(pts[k] - truth_pts[j]) for k, j in enumerate(fid) if j >= 0]
        hist_rows.append({"run": run, "iteration": it,
                          **{f"err_r0_{a}_m": float(v) for a, v in zip("xyz", r0 - tr["r_lvlh_m"][0])},
                          **{f"err_v0_{a}_mps": float(v) for a, v in zip("xyz", v0 - tr["v_lvlh_mps"][0])},
                          "err_ratio12": float(inertia[0] / inertia[2] - ratios_true[0]),
                          "err_ratio23": float(inertia[1] / inertia[2] - ratios_true[1]),
                          "err_I1_kgm2": float(inertia[0] / inertia[2] * I_true[2] - I_true[0]),
                          "err_I2_kgm2": float(inertia[1] / inertia[2] * I_true[2] - I_true[1]),
                          "err_points_rms_m": float(np.sqrt(np.mean(np.square(e_p)))) if e_p else np.nan,
                          **{f"err_p{k}_m": float(np.linalg.norm(pts[k] - truth_pts[j]))
                             for k, j in enumerate(fid) if j >= 0}})
    return hist_rows


def _stage2_rows(s2, t: _Truth, times, P, run: int):
    """Stage-2 table columns and errors: attitude (deg), r, v, ω (deg/s), attitude and ω also with relabelled axes."""
    tr, frames = t.tr, np.arange(len(times))
    e_att = np.array([np.degrees(np.linalg.norm(log_so3(a @ b.T))) for a, b in zip(s2.R, t.R)])
    e_r, e_v, e_w = s2.r - tr["r_lvlh_m"], s2.v - tr["v_lvlh_mps"], np.degrees(s2.w - tr["omega_body_rad_s"])
    s2_rows = {"run": [run] * len(frames), "method": ["stage2_cgkf"] * len(frames), "frame": frames.tolist(),
               "t_s": times.tolist(), "n_points": s2.n_points.tolist(), "has_result": (s2.flags == 0).tolist(),
               "reason": ["ok" if f == 0 else "no_measurement" for f in s2.flags],
               "diagnostics": [",".join(n for b, n in FLAG_NAMES.items() if int(f) & b) for f in s2.flags],
               "rms_px": s2.rms_px.tolist(), "err_att_deg": e_att.tolist(),
               "err_meas_r_m": np.linalg.norm(s2.r_meas - tr["r_lvlh_m"], axis=1).tolist()}
    for a, ax in enumerate("xyz"):
        s2_rows[f"est_r{ax}_m"] = s2.r[:, a].tolist()
        s2_rows[f"err_r{ax}_m"] = e_r[:, a].tolist()
        s2_rows[f"err_v{ax}_mps"] = e_v[:, a].tolist()
        s2_rows[f"est_w{ax}_deg_s"] = np.degrees(s2.w[:, a]).tolist()
        s2_rows[f"true_w{ax}_deg_s"] = np.degrees(tr["omega_body_rad_s"][:, a]).tolist()
        s2_rows[f"err_w{ax}_deg_s"] = e_w[:, a].tolist()
    # body-frame scores again with the principal axes relabelled to the truth's (discrete gauge)
    e_att_al = np.array([np.degrees(np.linalg.norm(log_so3(a @ P.T @ b.T))) for a, b in zip(s2.R, t.R)])
    e_w_al = np.degrees(s2.w @ P.T - tr["omega_body_rad_s"])
    s2_rows["err_att_aligned_deg"] = e_att_al.tolist()
    for a, ax in enumerate("xyz"):
        s2_rows[f"err_w{ax}_aligned_deg_s"] = e_w_al[:, a].tolist()
    return s2_rows, (e_att, e_r, e_v, e_w, e_att_al, e_w_al)


def _stage1_scores(s1, gf, obs, t: _Truth, truth_pts, fid, err, shape_err, ok_any) -> dict:
    """Summary scores of stage 1 against the truth (body frame and gauge-free), its CRLB σ and the FIM rank."""
    tr, R_true0, ratios_true, ok = t.tr, t.R0, t.ratios, fid >= 0
    return {
        "point_err_rms_m": float(np.sqrt(np.mean(err[ok] ** 2) * 3)) if ok.any() else np.nan,
        "point_err_max_m": float(np.max(np.linalg.norm(err[ok], axis=1))) if ok.any() else np.nan,
        "point_shape_err_rms_m": float(np.sqrt(np.nanmean(shape_err**2))) if ok_any else np.nan,
        "point_lvlh_err_rms_m": float(np.sqrt(np.mean(np.sum(
            ((s1.r0_lvlh + s1.points_body[ok] @ s1.R0_lvlh_from_body.T)
             - (tr["r_lvlh_m"][0] + truth_pts[fid[ok]] @ R_true0.T)) ** 2, 1)))) if ok.any() else np.nan,
        "w0_lvlh_err_deg_s": float(np.degrees(np.linalg.norm(s1.R0_lvlh_from_body @ s1.omega0_body
                                                             - R_true0 @ tr["omega_body_rad_s"][0]))),
        "r0_err_m": float(np.linalg.norm(s1.r0_lvlh - tr["r_lvlh_m"][0])),
        "v0_err_mps": float(np.linalg.norm(s1.v0_lvlh - tr["v_lvlh_mps"][0])),
        "att0_err_deg": float(np.degrees(np.linalg.norm(log_so3(s1.R0_lvlh_from_body @ R_true0.T)))),
        "w0_err_deg_s": float(np.degrees(np.linalg.norm(s1.omega0_body - tr["omega_body_rad_s"][0]))),
        "w0_norm_est_deg_s": float(np.degrees(np.linalg.norm(s1.omega0_body))),
        "w0_norm_true_deg_s": np.degrees(np.linalg.norm(tr["omega_body_rad_s"][0])),
        "w0_norm_sigma_deg_s": float(np.degrees(np.linalg.norm(s1.sigma_theta[9:12]))),  # per-axis body σ combined
        "w0_norm_crlb_deg_s": float(np.degrees(gf.omega_norm_sigma)),                     # CRLB of ‖ω0‖ itself
        "w0_lvlh_crlb_deg_s": float(np.degrees(np.linalg.norm(gf.omega_sigma))),
        "point_lvlh_crlb_rms_m": float(np.sqrt(np.mean(np.sum(gf.points_sigma[ok] ** 2, 1)))) if ok.any() else np.nan,
        "v0_crlb_mps": float(np.linalg.norm(s1.sigma_theta[3:6])),
        "ratio_I1_I3_est": float(s1.inertia_ratios[0]), "ratio_I2_I3_est": float(s1.inertia_ratios[1]),
        "ratio_I1_I3_true": float(ratios_true[0]), "ratio_I2_I3_true": float(ratios_true[1]),
        "ratio_err_max": float(np.max(np.abs(s1.inertia_ratios - ratios_true))),
        "ratio_sigma_1": float(s1.sigma_theta[12] * s1.inertia_ratios[0]),
        "ratio_sigma_2": float(s1.sigma_theta[13] * s1.inertia_ratios[1]),
        "inertia_tensor_lvlh_err_max": float(np.max(np.abs(_inertia_lvlh(s1.R0_lvlh_from_body,
                                                                        np.r_[s1.inertia_ratios, 1.0])
                                                          - _inertia_lvlh(R_true0, t.inertia)))),
        "fim_rank": obs.rank, "fim_params": obs.n_params}


def _stage2_scores(s2, e2: tuple, s1, P, truth_pts, fid, R_true0) -> dict:
    """Summary scores of stage 2, then of both stages with the principal axes relabelled to the truth's (P)."""
    e_att, e_r, e_v, e_w, e_att_al, e_w_al = e2
    mom = np.abs(P) @ np.r_[s1.inertia_ratios, 1.0]
    err_al = np.array([P @ s1.points_body[k] - truth_pts[j] for k, j in enumerate(fid) if j >= 0]).reshape(-1, 3)
    return {
        "stage2_pos_rms_m": float(np.sqrt(np.mean(np.sum(e_r**2, 1)))),
        "stage2_vel_rms_mps": float(np.sqrt(np.mean(np.sum(e_v**2, 1)))),
        "stage2_w_rms_deg_s": [float(v) for v in np.sqrt(np.mean(e_w**2, 0))],
        "stage2_att_rms_deg": float(np.sqrt(np.mean(e_att**2))),
        "stage2_flagged_frames": int(np.sum(s2.flags != 0)),
        "axes_relabelled": bool(not np.allclose(P, np.eye(3))),
        "axes_relabelling": " ".join(f"{v:+.0f}" for v in P.ravel()),
        "point_err_rms_aligned_m": float(np.sqrt(np.mean(err_al**2) * 3)) if len(err_al) else np.nan,
        "att0_err_aligned_deg": float(np.degrees(np.linalg.norm(log_so3(s1.R0_lvlh_from_body @ P.T @ R_true0.T)))),
        "ratio_I1_I3_aligned": float(mom[0] / mom[2]), "ratio_I2_I3_aligned": float(mom[1] / mom[2]),
        "stage2_att_rms_aligned_deg": float(np.sqrt(np.mean(e_att_al**2))),
        "stage2_w_rms_aligned_deg_s": [float(v) for v in np.sqrt(np.mean(e_w_al**2, 0))]}


def analyse_truthset(ts_path, rng: np.random.Generator, opts: StudyOptions = StudyOptions(),
                     progress: bool = False, run: int = 0) -> SequenceResult:
    """Run both stages on a microsat truth set (a folder, or an object with ``frames``, ``load``,
    ``read_table`` and ``len`` like :class:`renderlab.files.truthset.TruthSet`) and score them against its truth."""
    import pyarrow as pa
    from tqdm import tqdm

    ts = ts_path if hasattr(ts_path, "load") else TruthSet.open(ts_path)
    ts_path = getattr(ts, "path", ts_path)
    if "microsat" not in ts.frames[0]:
        raise UserError(f"truth set {ts_path} is not a microsat truth set (no 'microsat' frame metadata)")
    m0 = ts.frames[0]["microsat"]
    sq = _Sequence(CameraModel.from_dict(ts.frames[0]["camera"]), _rot(m0["quat_lvlh_from_cam_xyzw"]),
                   np.asarray(m0["camera_offset_lvlh_m"]), float(m0["mean_motion_rad_s"]),
                   np.array([r["time_s"] for r in ts.frames]))
    det = [detect_points(ts.load(i).dn, DetectOptions()) for i in tqdm(range(len(ts)), desc="detect",
                                                                         disable=not progress)]
    topts = TrackOptions(opts.epsilon_px, opts.min_track_frames)
    tracks = track_points(det, topts)
    db_all = build_database(tracks, topts)
    t = _truth(ts.frames)   # the seeded a-priori guess starts from the truth at the first frame
    s1, problem, rigid = _solve_stage1(sq, db_all, _apriori(t, sq.d, opts.prior, rng), opts, ts_path)
    db = problem.db
    obs = observability(problem, with_full_inertia(s1.theta), "full", prior=True)
    obs_noprior = observability(problem, with_full_inertia(s1.theta), "full", prior=False)
    gf = gauge_free(problem, s1.theta)
    feat = ts.read_table("features").to_pydict()
    truth_pts = np.column_stack([feat["x_body_m"], feat["y_body_m"], feat["z_body_m"]])
    ft = ts.read_table("feature_truth").to_pydict()
    fid = _match_tracks(tracks, db, ft, opts.match_px)
    pt_rows, err, shape_err, ok_any = _point_rows(s1, db, fid, truth_pts, gf, t, run)
    hist_rows = _history_rows(s1, problem, fid, truth_pts, t, run)
    s2 = run_stage2(det, np.arange(len(ts)), sq.times, sq.camera, sq.R_lc, sq.d, sq.n, s1.points_body,
                    s1.inertia_ratios, s1.r0_lvlh, s1.v0_lvlh, s1.R0_lvlh_from_body, s1.omega0_body,
                    Stage2Options(epsilon_px=opts.epsilon_px, sigma_px=opts.sigma_px))
    P = axis_relabelling(s1.R0_lvlh_from_body, t.R0)
    s2_rows, e2 = _stage2_rows(s2, t, sq.times, P, run)
    knobs = _match_tracks(tracks, db_all, ft, opts.match_px)[np.isin(db_all.track_ids, rigid.rejected)]
    summary = {
        "run": run, "frames": len(ts), "tracks": len(tracks), "database_points": db.n_points,
        "dropped_short_tracks": db.dropped_tracks, "matched_points": int((fid >= 0).sum()),
        "database_tracks_before_rigidity": db_all.n_points, "rigidity_rejected_tracks": rigid.rejected.tolist(),
        "rigidity_rejected_matched_knob": [int(v) for v in knobs],
        "rigidity_sigma_eff_px": rigid.sigma_eff_px, "rigidity_rounds": rigid.rounds,
        "stage1_inertia_fallback": s1.inertia_fallback,
        "stage1_rms_px": s1.rms_px, "stage1_nfev": s1.nfev, "stage1_njev": s1.njev,
        "stage1_status": s1.status, "stage1_converged": s1.converged, "stage1_message": s1.message,
        "stage1_cost0": s1.cost0, "stage1_cost": s1.cost, "stage1_gradient_inf_norm": s1.optimality,
        "stage1_seconds": s1.seconds, "stage1_measurements": int(len(db.frame)),
        **_stage1_scores(s1, gf, obs, t, truth_pts, fid, err, shape_err, ok_any),
        **_stage2_scores(s2, e2, s1, P, truth_pts, fid, t.R0)}
    tables = {"points": pa.table(pt_rows), "stage1_history": pa.table({k: [r.get(k, np.nan) for r in hist_rows]
                                                                      for k in hist_rows[0]}),
              "stage2": pa.table(s2_rows)}
    lines = (rigid.lines() + ["with range prior: " + s for s in obs.lines()]
             + ["images only: " + s for s in obs_noprior.lines()])
    return SequenceResult(tables, summary, lines, s1, s2, problem, gf)

