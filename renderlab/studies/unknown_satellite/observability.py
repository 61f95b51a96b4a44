"""How well do the images see the inertia ratios? Cramér–Rao σ from the Fisher information F = JᵀJ of the stage-1
model (Ivanov et al. eqs. 3-4, 7), linearised at the truth of a scenario, on a synthetic but geometric database of
the knobs that are in the image, unoccluded and lit; against arc length. Derivation and what the σ leave out
(systematic centroid errors: they are lower bounds): docs/unknown_satellite.md."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from estimators.pose import EstimationError, MeasurementDatabase, Stage1Options, Stage1Problem
from renderlab.errors import UserError, run_main
from renderlab.geometry.camera import CameraModel
from renderlab.geometry.rotations import skew
from renderlab.scenario import apply_overrides, load_scenario, scenario_from_dict
from renderlab.worlds.microsat.model import box_parts, build_parts
from renderlab.worlds.microsat.plan import separation_truth


@dataclass(frozen=True)
class ArcCase:
    """One arc: ``frames`` images ``dt_s`` apart, optional overrides of the scenario (``--set`` style)."""

    frames: int
    dt_s: float
    label: str = ""
    sets: tuple[str, ...] = ()


def segment_hits_box(p0: np.ndarray, p1: np.ndarray, centre, half) -> np.ndarray:
    """Whether the segments p0 → p1 (N, 3) pass through the axis-aligned box (slab test)."""
    d = p1 - p0
    lo, hi = np.asarray(centre) - half, np.asarray(centre) + half
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (lo - p0) / d, (hi - p0) / d
    tmin = np.where(np.isnan(t1), -np.inf, np.minimum(t1, t2))
    tmax = np.where(np.isnan(t2), np.inf, np.maximum(t1, t2))
    parallel_out = (d == 0) & ((p0 < lo) | (p0 > hi))
    t_in, t_out = tmin.max(1), tmax.min(1)
    return (t_in <= t_out) & (t_out > 1e-9) & (t_in < 1 - 1e-9) & ~parallel_out.any(1)


def visibility(truth, tips, camera, world, shadows: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """(visible (F, M) bool, pixel coordinates (F, M, 2)) of the knob centres in every frame; ``shadows``:
    a knob in the shadow of the bus or a panel counts as not visible (it is dark in the image)."""
    from scipy.spatial.transform import Rotation

    F, M = len(truth.times_s), len(tips)
    vis = np.zeros((F, M), bool)
    sl = np.full((F, M, 2), np.nan)
    boxes = box_parts(world)
    r_knob = world.knob_radius_m
    for k in range(F):
        R_lb = Rotation.from_quat(truth.quat_lvlh_from_body[k]).as_matrix()
        rho = (truth.rv_lvlh[k, :3] + tips @ R_lb.T - truth.camera_offset_lvlh) @ truth.R_lvlh_from_cam
        z = camera.project(rho)
        ok = (rho[:, 2] > 0) & camera.in_image(z)
        cam_b = R_lb.T @ (truth.camera_offset_lvlh - truth.rv_lvlh[k, :3])
        sun_b = R_lb.T @ truth.sun_lvlh[k]
        to_cam = cam_b - tips
        to_cam /= np.linalg.norm(to_cam, axis=1, keepdims=True)
        start_c = tips + 1.01 * r_knob * to_cam          # leave the knob itself
        start_s = tips + 1.01 * r_knob * sun_b
        far_s = tips + 50.0 * sun_b
        for c, h in boxes:
            ok &= ~segment_hits_box(start_c, np.broadcast_to(cam_b, tips.shape), c, h)
            if shadows:
                ok &= ~segment_hits_box(start_s, far_s, c, h)
        vis[k] = ok
        sl[k] = z
    return vis, sl


def synthetic_database(vis: np.ndarray, sl: np.ndarray, tracks: str = "segments", min_track_frames: int = 5):
    """A :class:`estimators.pose.MeasurementDatabase` of the true pixel positions and, per database point,
    the knob it belongs to."""
    if tracks not in ("segments", "ideal"):
        raise UserError(f"tracks must be 'segments' or 'ideal', got {tracks!r}")
    frame, point, z, knob = [], [], [], []
    for j in range(vis.shape[1]):
        idx = np.nonzero(vis[:, j])[0]
        if not len(idx):
            continue
        runs = [idx] if tracks == "ideal" else np.split(idx, np.nonzero(np.diff(idx) > 1)[0] + 1)
        for run in runs:
            if len(run) < min_track_frames:
                continue
            frame += run.tolist()
            point += [len(knob)] * len(run)
            z += sl[run, j].tolist()
            knob.append(j)
    db = MeasurementDatabase(np.arange(len(knob)), np.array(frame, int), np.array(point, int),
                             np.array(z, float).reshape(-1, 2))
    return db, np.array(knob, int)


def arc_information(scenario, case: ArcCase, *, sigma_px: float = 0.3, range_prior_sigma_m: float = 0.05,
                    tracks: str = "segments", min_track_frames: int = 5) -> dict:
    """Cramér–Rao σ of the inertia ratios (and ω0, r0, points) for one arc of ``scenario``."""
    from scipy.spatial.transform import Rotation

    data = apply_overrides(scenario.to_dict(), [f"trajectory.frames={case.frames}",
                                                 f"trajectory.dt_s={case.dt_s}", *case.sets])
    sc = scenario_from_dict(data, f"arc {case.label or case.frames}")
    _, tips = build_parts(sc.world)
    truth = separation_truth(sc, tips)
    camera = CameraModel.from_dict(sc.camera.model_dump())
    vis, sl = visibility(truth, tips, camera, sc.world)
    db, knob = synthetic_database(vis, sl, tracks, min_track_frames)
    row = {"label": case.label, "frames": case.frames, "dt_s": case.dt_s,
           "arc_s": float(case.dt_s * (case.frames - 1)), "tracks": tracks,
           "rotation_deg": float(np.degrees(np.sum(np.linalg.norm(truth.omega_body[:-1], axis=1) * case.dt_s))),
           "range_end_m": float(np.linalg.norm(truth.rv_lvlh[-1, :3] - truth.camera_offset_lvlh)),
           "visible_fraction": float(vis.mean()), "database_points": int(db.n_points),
           "measurements": int(len(db.frame))}
    nan = dict.fromkeys(("sigma_ratio_12", "sigma_ratio_23", "sigma_w0_deg_s", "sigma_w0_lvlh_deg_s", "sigma_r0_m",
                         "sigma_points_rms_m", "rel_min_singular_value"), np.nan)
    if db.n_points < 4 or db.frame.min() != 0:
        return {**row, **nan, "note": "fewer than 4 points / none from the first frame"}
    R0 = Rotation.from_quat(truth.quat_lvlh_from_body[0]).as_matrix()
    ratios = truth.inertia[:2] / truth.inertia[2]
    r0 = truth.rv_lvlh[0, :3]
    opts = Stage1Options(sigma_px=sigma_px, range_prior_sigma_m=range_prior_sigma_m)
    try:
        prob = Stage1Problem(camera, truth.R_lvlh_from_cam, truth.camera_offset_lvlh, truth.n, truth.times_s, db,
                             R0, float(np.linalg.norm(r0 - truth.camera_offset_lvlh)), opts)
    except EstimationError as exc:
        return {**row, **nan, "note": str(exc)}
    theta = np.r_[r0, truth.rv_lvlh[0, 3:], np.zeros(3), truth.omega_body[0], np.log(ratios), tips[knob].ravel()]
    J = prob.jacobian_analytic(theta, "ratios", prior=True)
    norms = np.linalg.norm(J, axis=0)
    s = np.linalg.svd(J / norms, compute_uv=False)
    Jn = J / norms
    cov = np.linalg.pinv(Jn.T @ Jn, rcond=1e-15) / np.outer(norms, norms)
    sig = np.sqrt(np.clip(np.diag(cov), 0, None))

    G = np.hstack([-R0 @ skew(truth.omega_body[0]), R0])      # ω_lvlh = R_ref exp([δφ]×) ω0 at δφ = 0
    cov_w = G @ cov[6:12, 6:12] @ G.T
    return {**row, "sigma_ratio_12": float(ratios[0] * sig[12]), "sigma_ratio_23": float(ratios[1] * sig[13]),
            "sigma_w0_deg_s": float(np.degrees(np.linalg.norm(sig[9:12]))),
            "sigma_w0_lvlh_deg_s": float(np.degrees(np.sqrt(np.trace(cov_w)))),
            "sigma_r0_m": float(np.linalg.norm(sig[0:3])),
            "sigma_points_rms_m": float(np.sqrt(np.mean(sig[14:] ** 2) * 3)),
            "rel_min_singular_value": float(s[-1] / s[0]), "note": ""}


#: the arcs of the published table: the paper's video (≈100 frames in 3 s), this lab's default (100 × 0.3 s),
#: longer arcs at the same and at lower frame rates, and the same with a slower separation (the target stays
#: closer, the knobs stay resolvable)
DEFAULT_ARCS = (
    ArcCase(100, 0.03, "paper video: 100 frames in 3 s"),
    ArcCase(100, 0.1, "100 frames, 10 s"),
    ArcCase(100, 0.3, "lab default: 100 frames, 30 s"),
    ArcCase(100, 0.6, "100 frames, 60 s"),
    ArcCase(200, 0.3, "200 frames, 60 s"),
    ArcCase(100, 1.2, "100 frames, 120 s"),
    ArcCase(400, 0.3, "400 frames, 120 s"),
    ArcCase(100, 0.3, "30 s, slow separation (v0_y = -0.04 m/s)", ("trajectory.v0_lvlh_mps=[0.01,-0.04,0.005]",)),
    ArcCase(100, 0.6, "60 s, slow separation", ("trajectory.v0_lvlh_mps=[0.01,-0.04,0.005]",)),
    ArcCase(100, 1.2, "120 s, slow separation", ("trajectory.v0_lvlh_mps=[0.01,-0.04,0.005]",)),
)


def inertia_observability_table(scenario, arcs=DEFAULT_ARCS, *, sigma_px: float = 0.3,
                                range_prior_sigma_m: float = 0.05, progress: bool = False):
    """:func:`arc_information` for every arc, both track models → a ``pyarrow.Table``."""
    import pyarrow as pa
    from tqdm import tqdm

    if scenario.world.kind != "microsat":
        raise UserError(f"inertia observability needs world.kind 'microsat', got '{scenario.world.kind}'")
    rows = [arc_information(scenario, c, sigma_px=sigma_px, range_prior_sigma_m=range_prior_sigma_m, tracks=t)
            for c in tqdm(arcs, desc="FIM vs arc", disable=not progress) for t in ("segments", "ideal")]
    return pa.Table.from_pylist(rows)


def main(argv=None) -> int:
    """``python -m renderlab.studies.unknown_satellite.observability SCENARIO --out FILE.parquet [--set K=V]``: the
    table of :func:`inertia_observability_table` (the lab's compact writer, written atomically), e.g. into a
    published study folder's ``tables/`` where its report draws it (:func:`.report_section.observability_blocks`)."""
    import argparse
    import os
    from pathlib import Path

    from renderlab.campaign.compact import write_compact

    ap = argparse.ArgumentParser(prog="python -m renderlab.studies.unknown_satellite.observability",
                                 description="Cramér–Rao σ of the inertia ratios against arc length (eq. 7)")
    ap.add_argument("scenario", help="microsat scenario TOML (e.g. scenes/unknown_satellite.toml)")
    ap.add_argument("--out", required=True, help="Parquet file to write")
    ap.add_argument("--set", action="append", default=[], dest="overrides", metavar="KEY=VALUE")
    args = ap.parse_args(argv)
    sc, _ = load_scenario(Path(args.scenario), args.overrides)
    table = inertia_observability_table(sc, progress=True)
    out = Path(args.out)
    tmp = out.with_name(f".{out.name}.{os.getpid()}")
    try:
        write_compact(table, tmp)
        os.replace(tmp, out)
    except OSError as exc:  # nothing half-written
        tmp.unlink(missing_ok=True)
        raise UserError(f"cannot write {args.out}: {exc.strerror or exc}") from None
    print(f"renderlab: wrote {out} ({table.num_rows} rows)")
    return 0


if __name__ == "__main__":
    raise SystemExit(run_main(main))
