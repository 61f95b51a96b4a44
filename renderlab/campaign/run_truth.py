"""The truth a campaign run measures: the nominal render, or the run's own perturbed one (``retina_vs_spc`` and
any study whose runs disperse the true trajectory or pointing).

Without truth perturbations every run measures the nominal descent, rendered once (truth cache keyed by
the scenario without its ``perturbations``/``campaign`` sections, :func:`renderlab.campaign.cache.cached_truthset`).

With them (``perturbations.position_sigma_m`` / ``position_cov_m2``, ``velocity_sigma_mps``,
``attitude_sigma_deg``) the run's *true* trajectory and pointing differ from the nominal ones, as in the
Monte Carlo of Wright et al. (Fig. 12): frame k of the nominal descent (time t_k, position p_k, attitude
R_k = R_render_from_cam) becomes

    p_k' = p_k + δp + δv · (t_k − t_0),        R_k' = R_k · Exp(δθ)

with δp ~ N(0, P_pos) (render = body-fixed frame), δv ~ N(0, diag σ_v²) and δθ ~ N(0, σ_θ²) per camera
axis — one draw per run (:func:`renderlab.campaign.perturb.draw_perturbation`, its ``position``,
``velocity`` and ``attitude`` streams; :func:`renderlab.campaign.perturb.perturb_pose`). The run renders its
own truth set at those poses (:func:`renderlab.campaign.cache.cached_frames_truthset`: keyed by the content
of the perturbed frame specs, so a re-run hits it; the world is loaded once per worker process). Its
manifest records the perturbed poses, so the landmark truth (true centre projected with the perturbed
pose), the a-priori pose drawn around the truth (:func:`renderlab.measurement.runner.draw_apriori`) and
the range/CRLB columns all follow the perturbed truth.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from renderlab.campaign.cache import cached_frames_truthset, cached_truthset, loaded_world
from renderlab.campaign.perturb import perturb_pose

#: the perturbations that change what is rendered
TRUTH_PERTURBATIONS = ("position_sigma_m", "position_cov_m2", "velocity_sigma_mps", "attitude_sigma_deg")


def truth_perturbations_on(p) -> list[str]:
    """The keys of the ``[perturbations]`` section ``p`` that disperse the true trajectory or pointing, in order."""
    return [n for n in TRUTH_PERTURBATIONS if getattr(p, n, None) is not None and np.any(np.asarray(getattr(p, n)) != 0)]


def perturbs_truth(p) -> bool:
    """Whether the ``[perturbations]`` section ``p`` disperses the true trajectory or pointing."""
    return bool(truth_perturbations_on(p))


def perturbed_specs(specs: list, draw) -> list:
    """The frame specs at the run's true poses (module docstring): position offset δp + δv·(t_k − t_0),
    pointing error R·Exp(δθ); camera, Sun and times unchanged."""
    t0 = float(specs[0].pose.time_s)
    out = []
    for s in specs:
        drift = np.asarray(draw.dvelocity_mps, float) * (float(s.pose.time_s) - t0)
        pos, R = perturb_pose(np.asarray(s.pose.position_m, float) + drift, s.pose.rotation, draw)
        out.append(dataclasses.replace(s, pose=dataclasses.replace(s.pose, position_m=pos, rotation=R)))
    return out


def truth_note(draw) -> dict:
    """The truth perturbation of a run, for the manifest (``frame_specs_note``)."""
    return {"truth_perturbation": {"dposition_m": [float(v) for v in draw.dposition_m],
                                   "dvelocity_mps": [float(v) for v in draw.dvelocity_mps],
                                   "attitude_rotvec_rad": [float(v) for v in draw.attitude_rotvec_rad]}}


def run_truthset(truth_scenario, base_dir, cache_root: Path, perturbations, draw) -> tuple[Path, bool]:
    """(path, cache hit) of the truth set this run measures: the nominal one when ``perturbations`` leave
    the truth alone, else the run's own render at :func:`perturbed_specs` of the nominal frames."""
    if not perturbs_truth(perturbations):
        return cached_truthset(truth_scenario, Path(base_dir), Path(cache_root))
    world = loaded_world(truth_scenario, Path(base_dir))
    specs = perturbed_specs(world.plan.frames, draw)
    return cached_frames_truthset(truth_scenario, Path(base_dir), Path(cache_root), specs, note=truth_note(draw))
