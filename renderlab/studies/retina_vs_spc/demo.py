"""The demo campaign: Retina vs SPC on a tiny EV5 descent, end to end, in a few minutes on a laptop: one Mitsuba
render of a small EV5 landing site (128², 3 frames, 4 spp; the truth cache serves every run), :data:`DEMO_RUNS` runs
of study ``retina_vs_spc`` in this process, then the campaign report. Running it again into the same folder resumes.
"""

from __future__ import annotations

import csv
from pathlib import Path

from renderlab import plugins
from renderlab.campaign.runner import run_campaign_file
from renderlab.errors import UserError
from renderlab.report.campaign_report import make_report

DEMO_RUNS = 40

DEMO_SCENARIO = """# renderlab demo campaign: Retina vs SPC on a tiny EV5 descent (written by renderlab.studies.retina_vs_spc.demo)
name = "ev5_demo_campaign"
description = "Tiny EV5 landing site (30 m at 5 cm, 4 m global facets), 128x128 camera, 65/45/30 m."

[world]
kind = "ev5"
seed = 5
facet_m = 4.0

[world.site]
extent_m = 30.0
cell_m = 0.05
taper_m = 1.0
crater_max_m = 3.0
boulder_min_m = 0.3

[[world.landmarks]]
name = "regional"
count = 10
spacing_m = 0.2
size = 15
radius_m = 6.0

[[world.landmarks]]
name = "site"
count = 10
spacing_m = 0.1
size = 15
radius_m = 2.5

[trajectory]
kind = "ev5_descent"
altitudes_m = [65.0, 45.0, 30.0]

[camera]
width = 128
height = 128
fx = 610.0
fy = 610.0
cx = 63.5
cy = 63.5

[render]
spp = 4
seed = 3
near_clip_m = 0.01

[perturbations]               # what the onboard system believes (1 sigma)
apriori_position_sigma_m = [0.2, 0.2, 0.2]
apriori_attitude_sigma_deg = 0.05
focal_length_sigma_frac = 0.0005
principal_point_sigma_px = 0.3
distortion_sigma = {k1 = 0.01}
maplet_spacing_sigma_frac = 0.1
sun_direction_sigma_deg = 0.5

[campaign]
seed = 7
"""


def demo_methods_section() -> str:
    """``[retina_vs_spc] methods``: Retina, SPC and the NCC baseline plug-in when it is installed (``setup.sh``
    installs ``examples/ncc_baseline``; a plain wheel install has only the lab's own two methods)."""
    methods = ["retina", "spc"] + (["ncc_baseline"] if "ncc_baseline" in plugins.landmark_methods else [])
    return "\n[retina_vs_spc]\nmethods = [" + ", ".join(f'"{m}"' for m in methods) + "]\n"


def run_demo_campaign(out_dir, progress: bool = True, runs: int = DEMO_RUNS) -> Path:
    """Run the demo campaign into ``out_dir`` (``scenario.toml``, ``campaign/``, ``report/``).

    Returns
    -------
    Path
        The report's ``index.html``.

    Raises
    ------
    UserError
        ``out_dir`` is a file, or holds a campaign of a different plan.
    """
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise UserError(f"--out {out} exists and is not a directory")
    out.mkdir(parents=True, exist_ok=True)
    scenario = out / "scenario.toml"
    scenario.write_text(DEMO_SCENARIO + demo_methods_section(), encoding="utf-8")
    campaign = out / "campaign"
    result = run_campaign_file(scenario, campaign, runs, workers=0, resume=campaign.exists(), progress=progress)
    if result.failed:
        first = result.failed[0]
        raise UserError(f"demo campaign: {len(result.failed)} of {runs} runs failed; run {first['run']}: {first['error']}")
    return make_report(campaign, out / "report")


def headline_table(summary_csv: Path) -> list[str]:
    """Markdown table of the report's headline: per method, on the well-measured subset (else all rows), bias and
    robust σ per axis and the no-result rate, with 95 % cluster-bootstrap intervals over landmark-frames."""
    if not Path(summary_csv).is_file():
        return ["(no summary.csv: the campaign report was not written)"]
    rows = list(csv.DictReader(Path(summary_csv).open(encoding="utf-8")))
    subset = "well_measured" if any(r["subset"] == "well_measured" for r in rows) else "all"
    rows = [r for r in rows if r["subset"] == subset]

    def iv(r, key, scale=1.0, signed=True):
        f = "{:+.3f}" if signed else "{:.3f}"
        v = [float(r[k]) * scale for k in (key, key + "_lo", key + "_hi")]
        return f"{f.format(v[0])} [{f.format(v[1])}, {f.format(v[2])}]"

    out = [f"Headline, {subset.replace('_', '-')} rows (95 % cluster-bootstrap intervals over landmark-frames):", "",
           "| method | bias Δs (px) | bias Δl (px) | robust σ Δs (px) | robust σ Δl (px) | no result (%) |",
           "|---|---:|---:|---:|---:|---:|"]
    for m in sorted({r["method"] for r in rows}):
        s_, l_ = (next(r for r in rows if r["method"] == m and r["axis"] == a) for a in "sl")
        out.append(f"| {m} | {iv(s_, 'bias_px')} | {iv(l_, 'bias_px')} | {iv(s_, 'robust_sigma_px', signed=False)} | "
                   f"{iv(l_, 'robust_sigma_px', signed=False)} | {iv(s_, 'no_result_rate', 100, signed=False)} |")
    return out
