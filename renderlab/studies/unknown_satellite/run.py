"""Campaign study ``unknown_satellite``: one run = one rendered separation through stage 1 and stage 2 of Ivanov et
al. (2018), with the run's own sensor noise, stage-1 initial values and (optionally) truth, each from its own child
of the run's ``SeedSequence``; tables ``scores``, ``stage2``, ``points``, ``stage1_history``, ``perturbations``
(what each draw and table is: docs/unknown_satellite.md)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from renderlab.campaign.cache import cached_truthset
from renderlab.campaign.perturb import refuse_unused
from renderlab.campaign.reexpose import ReexposedTruthSet
from renderlab.errors import UserError
from renderlab.files.truthset import TruthSet
from renderlab.scenario import scenario_from_dict, truth_dict
from renderlab.sensor.model import SensorOptions
from renderlab.studies.unknown_satellite.config import RUN_FLAGS, UnknownSatelliteStudyConfig
from renderlab.studies.unknown_satellite.sequence import PriorOptions, StudyOptions, analyse_truthset

#: generic [perturbations] keys this study uses; any other non-zero one is refused
USED_PERTURBATIONS = ("apriori_position_sigma_m", "apriori_velocity_sigma_mps", "apriori_attitude_sigma_deg",
                      "position_sigma_m", "velocity_sigma_mps")


def study_config(scenario):
    """The ``[unknown_satellite]`` section (defaults when absent)."""
    return getattr(scenario, "unknown_satellite", None) or UnknownSatelliteStudyConfig()


def draw_truth(scenario, seed_sequence: np.random.SeedSequence) -> dict:
    """The run's truth dispersion: ‖ω0‖ scale, q0 rotation vector (LVLH, rad), δr0, δv0 (one stream each)."""
    cfg, p = study_config(scenario), scenario.perturbations
    rate, att, pos, vel = (np.random.default_rng(s) for s in seed_sequence.spawn(4))
    return {"tumble_scale": float(1.0 + cfg.tumble_rate_sigma_frac * rate.standard_normal()),
            "q0_rotvec_rad": np.radians(cfg.initial_attitude_sigma_deg) * att.standard_normal(3),
            "dr0_m": np.asarray(p.position_sigma_m, float) * pos.standard_normal(3),
            "dv0_mps": np.asarray(p.velocity_sigma_mps, float) * vel.standard_normal(3)}


def truth_scenario_dict(scenario, draw: dict) -> dict:
    """What is rendered: the scenario without its campaign-only sections, with the truth draw applied
    (only where its σ is non-zero, so every run of a noise-only campaign has the same cache key)."""
    from scipy.spatial.transform import Rotation

    d = truth_dict(scenario.to_dict())
    cfg, p, tr = study_config(scenario), scenario.perturbations, d["trajectory"]
    if cfg.tumble_rate_sigma_frac > 0:
        tr["omega0_body_deg_s"] = [float(v * draw["tumble_scale"]) for v in tr["omega0_body_deg_s"]]
    if cfg.initial_attitude_sigma_deg > 0:
        q = Rotation.from_rotvec(draw["q0_rotvec_rad"]) * Rotation.from_quat(tr["q0_lvlh_from_body_xyzw"])
        tr["q0_lvlh_from_body_xyzw"] = [float(v) for v in q.as_quat()]
    if np.any(np.asarray(p.position_sigma_m) > 0):
        tr["r0_lvlh_m"] = [float(a + b) for a, b in zip(tr["r0_lvlh_m"], draw["dr0_m"])]
    if np.any(np.asarray(p.velocity_sigma_mps) > 0):
        tr["v0_lvlh_mps"] = [float(a + b) for a, b in zip(tr["v0_lvlh_mps"], draw["dv0_mps"])]
    return d


def score_row(summary: dict, run: int) -> dict:
    """The run's ``scores`` row (pose-table kind, :data:`renderlab.contracts.schemas.POSE_CORE`) from the
    sequence summary (scalars, lists flattened), with one boolean ``flag_<name>`` column per condition of
    :data:`~renderlab.studies.unknown_satellite.config.RUN_FLAGS` and their names in ``diagnostics``."""
    s = summary
    on = {"not_converged": not s["stage1_converged"], "inertia_boundary": bool(s["stage1_inertia_fallback"]),
          "rigidity_rejected": bool(s["rigidity_rejected_tracks"]), "stage2_gaps": bool(s["stage2_flagged_frames"]),
          "rank_deficient": s["fim_rank"] < s["fim_params"] - 1,
          "unmatched_point": s["matched_points"] < s["database_points"], "axes_relabelled": bool(s["axes_relabelled"])}
    row = {"run": int(run)}
    for k, v in s.items():
        if k in ("run", "stage1_message"):
            continue
        if k in ("stage2_w_rms_deg_s", "stage2_w_rms_aligned_deg_s"):
            row.update({k.replace("_w_", f"_w{a}_"): float(x) for a, x in zip("xyz", v)})
        elif k == "rigidity_rejected_tracks":
            row["rigidity_rejected"] = len(v)
        elif k == "rigidity_rejected_matched_knob":
            row["rigidity_rejected_knobs"] = sum(1 for x in v if x >= 0)
        else:  # text, flag, count or value
            row[k] = v if isinstance(v, str) else bool(v) if isinstance(v, (bool, np.bool_)) else (
                int(v) if isinstance(v, (int, np.integer)) else float(v))
    # principal axes may come out relabelled (x↔y etc.: the same images): compare the sorted moments too
    m_est = np.sort(np.array([s["ratio_I1_I3_est"], s["ratio_I2_I3_est"], 1.0]))
    m_true = np.sort(np.array([s["ratio_I1_I3_true"], s["ratio_I2_I3_true"], 1.0]))
    row["err_moments_sorted_max"] = float(np.max(np.abs(m_est / m_est.sum() - m_true / m_true.sum())))
    row["err_ratio_12_aligned"] = s["ratio_I1_I3_aligned"] - s["ratio_I1_I3_true"]
    row["err_ratio_23_aligned"] = s["ratio_I2_I3_aligned"] - s["ratio_I2_I3_true"]
    row["err_ratio_12"] = s["ratio_I1_I3_est"] - s["ratio_I1_I3_true"]
    row["err_ratio_23"] = s["ratio_I2_I3_est"] - s["ratio_I2_I3_true"]
    row["w0_norm_err_deg_s"] = s["w0_norm_est_deg_s"] - s["w0_norm_true_deg_s"]
    for name in RUN_FLAGS:
        row[f"flag_{name}"] = bool(on[name])
    row["has_result"], row["reason"] = True, "ok"  # a run that fails raises and is recorded as a failed run
    row["diagnostics"] = ",".join(n for n in RUN_FLAGS if on[n])
    row["stage1_message"] = str(s["stage1_message"])
    return row


def run(scenario, base_dir, run_index: int, seed_sequence, workdir) -> dict:
    """One run of ``unknown_satellite`` → ``{"scores", "stage2", "points", "stage1_history", "perturbations"}``."""
    import pyarrow as pa

    if scenario.world.kind != "microsat":
        raise UserError(f"study unknown_satellite needs world.kind 'microsat', got '{scenario.world.kind}'")
    p, cfg = scenario.perturbations, study_config(scenario)
    refuse_unused(p, USED_PERTURBATIONS, "study unknown_satellite does not use perturbations.{name}; supported: "
                  f"{', '.join(USED_PERTURBATIONS)} and the [unknown_satellite] section")
    ss_truth, ss_prior, ss_noise = seed_sequence.spawn(3)
    draw = draw_truth(scenario, ss_truth)
    truth_sc = scenario_from_dict(truth_scenario_dict(scenario, draw), "unknown_satellite truth scenario")
    path, hit = cached_truthset(truth_sc, Path(base_dir), Path(workdir) / "truth_cache")
    truth = TruthSet.open(path)   # sensor noise: the run's own, one child of ss_noise per frame
    ts = ReexposedTruthSet(truth, SensorOptions(**scenario.sensor.options_dict()), ss_noise.spawn(len(truth)),
                           rgb_fallback=True)
    prior = PriorOptions(sigma_r0_m=tuple(p.apriori_position_sigma_m), sigma_v0_mps=tuple(p.apriori_velocity_sigma_mps),
                         sigma_att_deg=p.apriori_attitude_sigma_deg, sigma_w_deg_s=cfg.apriori_omega_sigma_deg_s,
                         sigma_ratio_frac=cfg.apriori_ratio_sigma_frac, range_sigma_m=cfg.range_prior_sigma_m)
    opts = StudyOptions(prior=prior, sigma_px=cfg.sigma_px, epsilon_px=cfg.epsilon_px,
                        min_track_frames=cfg.min_track_frames, max_nfev=cfg.max_nfev)
    res = analyse_truthset(ts, np.random.default_rng(ss_prior), opts, run=int(run_index))
    row = score_row(res.summary, run_index)
    row["truth_cache_hit"] = bool(hit)
    row["truth_key"] = Path(path).name
    pert = {"run": int(run_index), "tumble_scale": draw["tumble_scale"],
            **{f"q0_rotvec_{a}_rad": float(v) for a, v in zip("xyz", draw["q0_rotvec_rad"])},
            **{f"dr0_{a}_m": float(v) for a, v in zip("xyz", draw["dr0_m"])},
            **{f"dv0_{a}_mps": float(v) for a, v in zip("xyz", draw["dv0_mps"])}}
    return {"scores": pa.table({k: [v] for k, v in row.items()}),
            "perturbations": pa.table({k: [v] for k, v in pert.items()}), **res.tables}
