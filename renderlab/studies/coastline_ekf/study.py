"""Campaign study ``coastline_ekf``: the coastline-navigation EKF of Straub & Christian from a scenario file
(``world.kind = "earth"``, ``trajectory.kind = "leo"``, a ``[coastline]`` section). ``coastline.mode`` picks
:func:`.geometric.run_batch` or :func:`.image.run_image_study`; both return the ``coastline_filter`` table, the image
mode also ``coastline_frames``. The scenario keys → study options table: docs/coastline_ekf.md.
"""

from __future__ import annotations

import math
from pathlib import Path

from renderlab.builtin import scene_path
from renderlab.campaign.runner import run_campaign_file
from renderlab.errors import UserError
from renderlab.report.campaign_report import make_report
from renderlab.studies.coastline_ekf import publish, report_section
from renderlab.studies.coastline_ekf.config import CoastlineStudyConfig, check_perturbations
from renderlab.studies.coastline_ekf.geometric import TRUTH_FIELDS, CoastlineGeometricOptions, run_batch
from renderlab.studies.coastline_ekf.image import run_image_study
from renderlab.worlds.earth import wgs84

__all__ = ["geometric_options", "run", "report_sections", "run_demo_coastline"]


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


def geometric_options(scenario):
    """:class:`CoastlineGeometricOptions` of a validated scenario (UserError on what the study cannot do)."""
    c = _section(scenario)
    tr, p = scenario.trajectory, scenario.perturbations
    check_perturbations(p)
    if tr.eccentricity != 0:
        raise UserError("study coastline_ekf: trajectory.eccentricity must be 0 (the paper's circular orbits)")
    gmst0 = float(wgs84.gmst_rad(wgs84.julian_date(wgs84.parse_epoch(tr.epoch_utc), 0.0)))  # ECEF = R3(GMST) ECI
    return CoastlineGeometricOptions(**{k: getattr(tr, k) for k in TRUTH_FIELDS if hasattr(tr, k)},
        altitude_m=tr.altitude_km * 1e3, inclination_rad=math.radians(tr.inclination_deg),
        raan_rad=math.radians(tr.raan_deg), argp_rad=math.radians(tr.argp_deg),
        nu0_rad=math.radians(tr.true_anomaly_deg), gmst0_rad=gmst0, truth_j2=tr.j2,
        duration_s=c.duration_s, cadence_s=tr.dt_s, fov_rad=fov_rad(scenario), points_per_image=c.points_per_image,
        db_spacing_m=c.db_spacing_m, sigma_theta_rad=c.sigma_theta_mrad * 1e-3,
        sigma_star_tracker_rad=math.radians(tr.star_tracker_sigma_arcsec / 3600.0),
        sigma_r0_m=tuple(float(v) for v in p.apriori_position_sigma_m),
        sigma_v0_mps=tuple(float(v) for v in p.apriori_velocity_sigma_mps),
        q_acc_m2_s3=c.process_noise_m2_s3, filter_step_s=c.filter_step_s, t0_s=tr.start_s).validate()


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
    folder (:mod:`.publish`) gets one section per orbit, a published image folder with a ``geometric_filter``
    table the comparison of its modes (:func:`.report_section.comparison_sections`)."""
    if publish.is_geometric(tables):
        return publish.report_sections(tables, Path(stage))
    frames = tables.get("coastline_frames")
    rs = report_section
    out = [rs.coastline_section(name, t, Path(stage), frames=frames) for name, t in sorted(tables.items())
           if rs.is_coastline_table(t) and not rs.is_comparison_table(name)]
    return out + rs.comparison_sections(tables, Path(stage))


def run_demo_coastline(out, progress: bool = True, runs: int = 16) -> dict:
    """Demo piece: a small geometric coastline-EKF campaign (``scenes/coastline_ekf.toml``, 90°/1000 km,
    half an orbit, ``runs`` seeded runs) and its report (Figs. 5-9 style, ANEES/ANIS). ≈30 s on 2 cores, most
    of it loading GSHHG. Returns the campaign and report paths, the steady-state numbers and ``summary``, one
    line for the demo's output."""
    import csv

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
