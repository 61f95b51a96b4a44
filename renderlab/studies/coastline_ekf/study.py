r"""Campaign study ``coastline_ekf``: the coastline-navigation EKF of Straub & Christian from a scenario file.

A scenario with ``world.kind = "earth"``, ``trajectory.kind = "leo"`` and a ``[coastline]`` section
(:class:`renderlab.studies.coastline_ekf.config.CoastlineStudyConfig`) maps onto the study options:

=============================  ======================================================================
scenario key                   study option
=============================  ======================================================================
trajectory.altitude_km,        circular orbit (eq. 10-12; the paper's RAAN = ω = ν = 0 are the defaults),
inclination_deg, raan_deg,     truth two-body or J2 (``trajectory.j2``); eccentricity must be 0
argp_deg, true_anomaly_deg
trajectory.epoch_utc           Earth rotation angle (GMST) at t = 0
trajectory.start_s             filter start: the prior is at ``start_s``, images every ``dt_s`` after it
trajectory.dt_s                measurement cadence (paper: 30 s)
trajectory.fov_deg             square field of view (paper: 30°; None: from camera.width and fx)
trajectory.star_tracker_...    star-tracker noise per axis (shared by all LOS of an image)
perturbations.apriori_*        initial dispersion per ECI axis (paper: 500 m, 5 mm/s)
coastline.*                    mode, σθ (eq. 18), points per image, duration, process noise, image options
=============================  ======================================================================

``mode = "geometric"`` runs :func:`renderlab.studies.coastline_ekf.geometric.run_batch` for the run's seed
sequence; ``mode = "image"`` runs :func:`renderlab.studies.coastline_ekf.image.run_image_study`. Both return the
design's filter table (``run, t_s, err_r/i/c_m, err_vr/vi/vc_mps, sig_*, nees, nis, n_meas``) under the name
``coastline_filter``; the image mode adds ``coastline_frames`` (per-image extraction/matching diagnostics).
"""

from __future__ import annotations

import math

from renderlab.builtin import scene_path
from renderlab.campaign.runner import run_campaign_file
from renderlab.errors import UserError
from renderlab.report.campaign_report import make_report
from renderlab.studies.coastline_ekf import comparison, published
from renderlab.studies.coastline_ekf.config import CoastlineStudyConfig
from renderlab.studies.coastline_ekf.geometric import CoastlineGeometricOptions, run_batch
from renderlab.studies.coastline_ekf.image import run_image_study
from renderlab.studies.coastline_ekf.report_section import coastline_section, is_coastline_table
from renderlab.studies.coastline_ekf.truth_options import TRUTH_FIELDS, with_truth
from renderlab.worlds.earth import wgs84

__all__ = ["geometric_options", "run", "check_perturbations"]

from renderlab.studies.coastline_ekf.config import SUPPORTED_PERTURBATIONS, check_perturbations  # noqa: F401,E402


def _section(scenario):
    if scenario.world.kind != "earth" or scenario.trajectory.kind != "leo":
        raise UserError(f"study coastline_ekf needs world.kind = 'earth' and trajectory.kind = 'leo', got "
                        f"'{scenario.world.kind}' / '{scenario.trajectory.kind}'")
    return scenario.coastline if scenario.coastline is not None else CoastlineStudyConfig()


def fov_rad(scenario) -> float:
    """The study's square field of view: ``trajectory.fov_deg`` or the camera's horizontal FOV."""
    tr, cam = scenario.trajectory, scenario.camera
    if tr.fov_deg is not None:
        return math.radians(tr.fov_deg)
    return 2.0 * math.atan(0.5 * cam.width / cam.fx)


def gmst_at_epoch(epoch_utc: str) -> float:
    """Earth rotation angle (rad) at the scenario's epoch (the Earth world's ECI → ECEF is R3(GMST))."""
    return float(wgs84.gmst_rad(wgs84.julian_date(wgs84.parse_epoch(epoch_utc), 0.0)))


def geometric_options(scenario):
    """:class:`CoastlineGeometricOptions` of a validated scenario (UserError on what the study cannot do)."""
    c = _section(scenario)
    tr, p = scenario.trajectory, scenario.perturbations
    check_perturbations(p)
    if tr.eccentricity != 0:
        raise UserError("study coastline_ekf: trajectory.eccentricity must be 0 (the paper's circular orbits)")
    opts = CoastlineGeometricOptions(
        altitude_m=tr.altitude_km * 1e3, inclination_rad=math.radians(tr.inclination_deg),
        raan_rad=math.radians(tr.raan_deg), argp_rad=math.radians(tr.argp_deg),
        nu0_rad=math.radians(tr.true_anomaly_deg), gmst0_rad=gmst_at_epoch(tr.epoch_utc), truth_j2=tr.j2,
        duration_s=c.duration_s, cadence_s=tr.dt_s, fov_rad=fov_rad(scenario), points_per_image=c.points_per_image,
        db_spacing_m=c.db_spacing_m, sigma_theta_rad=c.sigma_theta_mrad * 1e-3,
        sigma_star_tracker_rad=math.radians(tr.star_tracker_sigma_arcsec / 3600.0),
        sigma_r0_m=tuple(float(v) for v in p.apriori_position_sigma_m),
        sigma_v0_mps=tuple(float(v) for v in p.apriori_velocity_sigma_mps),
        q_acc_m2_s3=c.process_noise_m2_s3, filter_step_s=c.filter_step_s, t0_s=tr.start_s).validate()
    if getattr(tr, "truth_model", "j2_rk4") == "j2_rk4":
        return opts

    return with_truth(opts, **{k: getattr(tr, k) for k in TRUTH_FIELDS})


def run(scenario, base_dir, run_index: int, seed_sequence, workdir) -> dict:
    """Campaign-engine entry point: one run → ``{"coastline_filter": table, ...}`` (module docstring)."""
    c = _section(scenario)
    if c.mode == "image":

        return run_image_study(scenario, base_dir, run_index, seed_sequence, workdir)

    o = geometric_options(scenario)
    return {"coastline_filter": run_batch(o, [seed_sequence], [run_index])["table"]}


def report_sections(tables: dict, stage) -> list[tuple[str, str]]:
    """``renderlab report`` hook: the coastline section (Figs. 5-9, ANEES/ANIS with 2m-dof bands) per filter table
    (the image mode's ``coastline_frames`` table, when present, explains its consistency); a published geometric
    folder (:mod:`.published`) gets one section per orbit, a published image folder with a ``geometric_filter``
    table the comparison of its modes (:mod:`.comparison`)."""
    from pathlib import Path


    if published.is_geometric(tables):
        return published.report_sections(tables, Path(stage))
    frames = tables.get("coastline_frames")
    out = [coastline_section(name, t, Path(stage), frames=frames) for name, t in sorted(tables.items())
           if is_coastline_table(t) and not comparison.is_comparison_table(name)]
    return out + comparison.report_sections(tables, Path(stage))


def run_demo_coastline(out, progress: bool = True, runs: int = 16) -> dict:
    """Demo piece: a small geometric coastline-EKF campaign (``scenes/coastline_ekf.toml``, 90°/1000 km,
    half an orbit, ``runs`` seeded runs) and its report (Figs. 5-9 style, ANEES/ANIS). ≈30 s on 2 cores, most
    of it loading GSHHG. Returns the campaign and report paths, the steady-state numbers and ``summary``, one
    line for the demo's output."""
    import csv
    from pathlib import Path


    out = Path(out)

    scene = scene_path("coastline_ekf.toml")
    camp = out / "coastline_campaign"
    res = run_campaign_file(scene, camp, runs, overrides=["coastline.duration_s=3000"], workers=0,
                            resume=(camp / "campaign.json").is_file(), progress=progress)
    page = make_report(camp, out / "coastline_report")
    with open(out / "coastline_report" / "coastline_filter_coastline_steady_state.csv") as f:
        steady = {k: v for k, v in next(csv.DictReader(f)).items()}
    f = {k: float(v) for k, v in steady.items() if k.startswith(("mc_", "filter_", "nis_total_over", "anees_"))}
    summary = (f"coastline EKF, 90°/1000 km, {res.runs} runs over {float(steady['window_end_s']) / 60:.0f} min: "
               f"steady-state 3σ position R/I/C {f['mc_3sig_r_m']:.0f}/{f['mc_3sig_i_m']:.0f}/{f['mc_3sig_c_m']:.0f} m "
               f"(filter {f['filter_3sig_r_m']:.0f}/{f['filter_3sig_i_m']:.0f}/{f['filter_3sig_c_m']:.0f} m), "
               f"ANEES inside its 99 % band at {100 * f['anees_inside_99_fraction']:.0f} % of times, "
               f"NIS/dof {f['nis_total_over_dof']:.3f}")
    return {"campaign": camp, "report": page, "runs": res.runs, "failed": len(res.failed), "steady_state": steady,
            "summary": summary}
