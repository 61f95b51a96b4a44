"""Study ``analytic_pointing``: where is the sphere in the image? An end-to-end exercise of the engine.

Each run perturbs an analytic scenario (:mod:`renderlab.campaign.perturb`), renders every frame from the perturbed
(true) pose through the truth cache and measures the sphere's centre with the two image-only methods of
:mod:`estimators.centre_limb.blob` (``centroid``, ``ellipse``), seeded at the centre predicted from the nominal
camera and the a-priori pose. Truth: the true centre projected through the true camera and pose (Wright et al.
eqs. 1-4). Extra columns (``docs/analytic_pointing.md``): phase, range, GSD ratio, the truth render's centre of light,
the true apparent radius, shadow fraction, albedo contrast and the registration CRLB in the window.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from estimators.centre_limb.blob import METHODS, measure_sphere
from renderlab.campaign.cache import cached_truthset
from renderlab.campaign.perturb import draw_perturbation, perturb_pose, perturb_scenario_dict
from renderlab.campaign.scoring import dn_variance, registration_crlb
from renderlab.contracts.reasons import LandmarkReason as R
from renderlab.contracts.schemas import LANDMARK_CORE, table_from_rows
from renderlab.errors import UserError
from renderlab.files.truthset import TruthSet
from renderlab.geometry.camera import CameraModel
from renderlab.scenario import scenario_from_dict, truth_dict
from renderlab.sensor.model import SensorOptions, expected_dn
from renderlab.worlds.base import frame_specs


def _target(scenario):
    want = scenario.campaign.target
    for k, b in enumerate(scenario.world.bodies):
        if (want and b.name == want) or (not want and b.shape == "sphere"):
            if b.shape != "sphere":
                raise UserError(f"campaign.target '{want}' is a {b.shape}; analytic_pointing needs a sphere")
            return k, np.asarray(b.center_m, float), float(b.radius_m)
    raise UserError(f"campaign.target: no sphere named '{want}' in world.bodies" if want
                    else "analytic_pointing needs a sphere in world.bodies")


def _truth_scenario(sc_dict: dict, position, R, seed: int) -> dict:
    d = truth_dict(sc_dict)
    d["trajectory"] = {"kind": "line", "frames": 1, "dt_s": 1.0, "start_m": [float(v) for v in position],
                       "target_m": [float(v) for v in position + R.as_matrix()[:, 2]],
                       "up": [float(v) for v in -R.as_matrix()[:, 1]]}
    d["render"] = {**d["render"], "seed": int(seed)}
    return d


def _frame_truth(fr, body_id: int, center, sun_dir, win_sl, half: int, opts):
    """Truth-only columns of a frame: shadow fraction, albedo contrast, CRLB in the window."""
    is_t = fr.id == body_id
    lit = np.einsum("hwk,k->hw", np.nan_to_num(fr.normal), sun_dir) > 0
    shadow = float(np.mean(~lit[is_t])) if is_t.any() else math.nan
    h, w = fr.id.shape
    c = np.rint(win_sl).astype(int)
    sl_ = (slice(max(c[1] - half, 0), min(c[1] + half + 1, h)), slice(max(c[0] - half, 0), min(c[0] + half + 1, w)))
    rad = np.asarray(fr.radiance, np.float64)
    t_in, o_in = is_t[sl_], (~is_t[sl_]) & (fr.id[sl_] >= 0)
    lt = rad[sl_][t_in].mean() if t_in.any() else math.nan
    lo = rad[sl_][o_in].mean() if o_in.any() else 0.0
    contrast = (lt - lo) / (lt + lo) if lt + lo > 0 else math.nan
    edn = expected_dn(rad, opts)[sl_]
    if min(edn.shape) < 7:
        return shadow, contrast, math.nan, math.nan
    crlb = registration_crlb(edn, dn_variance(rad, opts)[sl_])
    return shadow, contrast, crlb[0], crlb[1]


def _centre_of_light(fr, body_id: int) -> tuple[float, float]:
    """Radiance-weighted centroid (s, l) of the target's pixels in the noise-free truth render (NaN if unlit)."""
    if fr.radiance is None:
        return math.nan, math.nan
    on = (fr.id == body_id) & np.isfinite(fr.radiance)
    w = np.where(on, np.asarray(fr.radiance, np.float64), 0.0)
    if not w.sum() > 0:
        return math.nan, math.nan
    ll, ss = np.indices(w.shape)
    return float((w * ss).sum() / w.sum()), float((w * ll).sum() / w.sum())


def run(scenario, base_dir, run_index: int, seed_sequence, workdir) -> dict:
    """One run of ``analytic_pointing`` → ``{"measurements": table, "perturbations": table}``."""
    import dataclasses

    import pyarrow as pa
    from scipy.spatial.transform import Rotation

    if scenario.world.kind != "analytic":
        raise UserError(f"study analytic_pointing needs world.kind 'analytic', got '{scenario.world.kind}'")
    body_id, center, radius = _target(scenario)
    ss_pert, ss_render = seed_sequence.spawn(2)
    draw = draw_perturbation(scenario.perturbations, ss_pert)
    specs = frame_specs(scenario, Path(base_dir))
    render_seeds = [int(s.generate_state(1)[0]) for s in ss_render.spawn(len(specs))]
    truth_base = perturb_scenario_dict(scenario.to_dict(), draw)
    cam_nom = CameraModel.from_dict(scenario.camera.model_dump())
    base_opts = SensorOptions(**scenario.sensor.options_dict())
    rows = []
    for spec, rseed in zip(specs, render_seeds):
        pos_t, R_t = perturb_pose(spec.pose.position_m, spec.pose.rotation, draw)
        truth_sc = scenario_from_dict(_truth_scenario(truth_base, pos_t, R_t, rseed), "perturbed scenario")
        path, _ = cached_truthset(truth_sc, Path(base_dir), Path(workdir) / "truth_cache")
        fr = TruthSet.open(path).load(0)
        cam_t = CameraModel.from_dict(fr.meta["camera"])
        pos_m = np.asarray(fr.meta["pose"]["position_m"])
        R_m = Rotation.from_quat(fr.meta["pose"]["quat_render_from_cam_xyzw"])
        sun_t = np.asarray(fr.meta["sun"]["direction_render"])
        truth_sl = cam_t.project(R_m.inv().apply(center - pos_m))
        pos_prior = spec.pose.position_m + draw.apriori_dposition_m
        p_prior = spec.pose.rotation.inv().apply(center - pos_prior)
        pred_sl = cam_nom.project(p_prior)
        rng_nom = float(np.linalg.norm(p_prior))
        r_px = cam_nom.fx * math.tan(math.asin(min(radius / rng_nom, 0.999)))
        res = measure_sphere(fr.dn, pred_sl, r_px)
        rng_t = float(np.linalg.norm(pos_m - center))
        to_cam = (pos_m - center) / rng_t
        phase = math.degrees(math.acos(float(np.clip(np.dot(to_cam, sun_t), -1, 1))))
        opts = dataclasses.replace(base_opts, exposure_s=float(fr.meta["sensor"]["exposure_s"]))
        half = int(math.ceil(1.5 * r_px + 4))
        shadow, contrast, crlb_s, crlb_l = _frame_truth(fr, body_id, center, sun_t, truth_sl, half, opts)
        gsd_ratio = (rng_t / cam_t.fx) / (rng_nom / cam_nom.fx)
        light = _centre_of_light(fr, body_id)
        radius_px = 0.5 * (cam_t.fx + cam_t.fy) * math.tan(math.asin(min(radius / rng_t, 0.999)))
        for method in METHODS:
            ms, ml, score, reason, t_ms = res[method]
            rows.append({
                "campaign": scenario.name, "run": int(run_index), "frame": int(spec.index), "item": body_id,
                "method": method, "pred_s": float(pred_sl[0]), "pred_l": float(pred_sl[1]),
                "meas_s": ms, "meas_l": ml, "truth_s": float(truth_sl[0]), "truth_l": float(truth_sl[1]),
                "err_s": ms - float(truth_sl[0]), "err_l": ml - float(truth_sl[1]),
                "score": score, "has_result": reason == R.OK.value, "reason": reason, "outlier": False,
                "diagnostics": "" if reason == R.OK.value else reason, "t_ms": float(t_ms),
                "phase_deg": phase, "range_m": rng_t, "gsd_ratio": gsd_ratio, "shadow_fraction": shadow,
                "albedo_contrast": float(contrast), "crlb_s": float(crlb_s), "crlb_l": float(crlb_l),
                "centre_of_light_s": light[0], "centre_of_light_l": light[1], "target_radius_px": radius_px,
            })

    meas = table_from_rows(rows, LANDMARK_CORE, "landmark")
    prow = {"campaign": scenario.name, "run": int(run_index), **draw.to_row()}
    return {"measurements": meas, "perturbations": pa.table({k: [v] for k, v in prow.items()})}
