"""The demo piece of the unknown-satellite study, small enough for ``renderlab demo``: one Mitsuba render of the
Chibis-M-like separation (8 frames 4 s apart, 256×192), :data:`DEMO_RUNS` campaign runs of study
``unknown_satellite`` and their report (Figs 5-7, 13-14). About 15 s on 2 cores; running it again resumes."""

from __future__ import annotations

from pathlib import Path

from renderlab.builtin import scene_path
from renderlab.campaign.runner import run_campaign_file
from renderlab.campaign.store import load_tables
from renderlab.report.campaign_report import make_report

DEMO_RUNS = 4

#: the demo scenario: the built-in ``scenes/unknown_satellite.toml`` at 256×192, 8 frames 4 s apart, a slower
#: separation, 2 spp, with stage-1 initial-value errors (``renderlab show unknown_satellite --set ...`` shows it)
DEMO_SETS = ('name="unknown_satellite_demo"',
             'description="Chibis-M-like microsatellite after separation: 8 frames 4 s apart, 256x192."',
             "camera.width=256", "camera.height=192", "camera.fx=222.0", "camera.fy=222.0", "camera.cx=127.5",
             "camera.cy=95.5", "render.spp=2", "trajectory.frames=8", "trajectory.dt_s=4.0",
             "trajectory.v0_lvlh_mps=[0.01,-0.04,0.005]", "perturbations.apriori_position_sigma_m=[0.03,0.03,0.03]",
             "perturbations.apriori_velocity_sigma_mps=[0.01,0.01,0.01]", "perturbations.apriori_attitude_sigma_deg=3.0",
             "unknown_satellite.min_track_frames=4", "unknown_satellite.epsilon_px=15.0", "campaign.seed=9")


def run_demo_unknown_satellite(out: Path, progress: bool = True, runs: int = DEMO_RUNS) -> dict:
    """Render, run the small campaign (``runs`` runs) into ``out/campaign`` and its report into ``out/report``; returns
    the page, folder, run counts, the medians over runs of the scores the demo page quotes (cm, °/s, cm/s), the
    smallest FIM rank of eq. 7 and the ``flag_names`` raised."""
    import numpy as np

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    camp = out / "campaign"
    res = run_campaign_file(scene_path("unknown_satellite.toml"), camp, runs, overrides=list(DEMO_SETS), workers=0,
                            resume=(camp / "campaign.json").is_file(), progress=progress)
    page = make_report(camp, out / "report")
    sc = load_tables(camp)["scores"].to_pydict()

    def med(key, scale=1.0):
        v = np.asarray(sc.get(key, [np.nan]), float)
        return float(np.median(v[np.isfinite(v)]) * scale) if np.isfinite(v).any() else float("nan")
    return {"report": page, "campaign": camp, "runs": res.runs, "failed": len(res.failed),
            "failed_errors": [f"run {f['run']}: {f['error']}" for f in res.failed],
            "point_lvlh_err_cm": med("point_lvlh_err_rms_m", 100), "point_lvlh_crlb_cm": med("point_lvlh_crlb_rms_m", 100),
            "w0_norm_est_deg_s": med("w0_norm_est_deg_s"), "w0_norm_true_deg_s": med("w0_norm_true_deg_s"),
            "w0_norm_err_deg_s": med("w0_norm_err_deg_s"), "w0_norm_crlb_deg_s": med("w0_norm_crlb_deg_s"),
            "stage2_vel_rms_cm_s": med("stage2_vel_rms_mps", 100),
            "ratio_err_12": med("err_ratio_12_aligned"), "ratio_err_23": med("err_ratio_23_aligned"),
            "ratio_sigma_1": med("ratio_sigma_1"), "ratio_sigma_2": med("ratio_sigma_2"),
            "fim_rank": int(np.min(sc["fim_rank"])), "fim_params": int(np.max(sc["fim_params"])),
            "runs_scored": len(sc["run"]),
            "flag_names": sorted({n for f in sc["diagnostics"] for n in str(f).split(",") if n})}
