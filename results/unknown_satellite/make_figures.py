"""Unknown-satellite study, one small sequence: run it (``--run``) and draw figures like Ivanov et al. Figs 5-7, 13-14.

    .venv/bin/python results/unknown_satellite/make_figures.py --run [--work DIR]   # render + both stages + figures
    .venv/bin/python results/unknown_satellite/make_figures.py --analyse [--work DIR]  # both stages on DIR/truthset
    .venv/bin/python results/unknown_satellite/make_figures.py                      # figures from the tables here

Tables (Parquet) and summary.json are written next to this script; the truth set goes to --work.
"""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
SETS: list[str] = []   # the scene as it is: 100 frames at 3.3 frames/s (30 s), 640×480, 60° field of view


def run(work: Path, seed: int, render: bool = True) -> None:
    from renderlab.scenario import load_scenario
    from renderlab.studies.unknown_satellite.sequence import run_sequence

    sc, base = load_scenario(REPO / "scenes" / "unknown_satellite.toml", SETS)
    run_sequence(sc, base, work, seed=seed, progress=True, render=render)
    for name in ("points.parquet", "stage1_history.parquet", "stage2.parquet", "summary.json"):
        shutil.copy(work / name, HERE / name)
    shutil.copy(work / "truthset" / "contact_sheet.png", HERE / "contact_sheet.png")


def figures() -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import pyarrow.parquet as pq

    h = pq.read_table(HERE / "stage1_history.parquet").to_pydict()
    it = np.array(h["iteration"])
    fig, ax = plt.subplots(1, 2, figsize=(9, 3.5), constrained_layout=True)
    for a in "xyz":
        ax[0].plot(it, 100 * np.array(h[f"err_r0_{a}_m"]), label=a)
        ax[1].plot(it, 100 * np.array(h[f"err_v0_{a}_mps"]), label=a)
    ax[0].set(xlabel="iteration", ylabel="error of r0 (cm)", title="(a) initial centre-of-mass position")
    ax[1].set(xlabel="iteration", ylabel="error of v0 (cm/s)", title="(b) initial velocity")
    for a_ in ax:
        a_.legend(), a_.grid(alpha=.3)
    fig.savefig(HERE / "fig5_stage1_position_velocity.png", dpi=110)
    fig, ax = plt.subplots(figsize=(5, 3.5), constrained_layout=True)
    ax.plot(it, h["err_I1_kgm2"], label="I1 (with true I3)")
    ax.plot(it, h["err_I2_kgm2"], label="I2 (with true I3)")
    ax.set(xlabel="iteration", ylabel="error (kg m²)", title="inertia from the estimated ratios")
    ax.legend(), ax.grid(alpha=.3)
    fig.savefig(HERE / "fig6_stage1_inertia.png", dpi=110)
    fig, ax = plt.subplots(figsize=(5, 3.5), constrained_layout=True)
    for k in [c for c in h if c.startswith("err_p") and c.endswith("_m") and c != "err_points_rms_m"]:
        ax.semilogy(it, np.array(h[k]) * 100, label=k[4:-2])
    ax.set(xlabel="iteration", ylabel="point error (cm)", title="reference points (body frame)")
    ax.legend(fontsize=7), ax.grid(alpha=.3)
    fig.savefig(HERE / "fig7_stage1_points.png", dpi=110)
    s2 = pq.read_table(HERE / "stage2.parquet").to_pydict()
    t = np.array(s2["t_s"])
    fig, ax = plt.subplots(1, 2, figsize=(9, 3.5), constrained_layout=True)
    for a in "xyz":
        ax[0].plot(t, s2[f"est_r{a}_m"], label=f"{a} estimated")
        ax[0].plot(t, np.array(s2[f"est_r{a}_m"]) - np.array(s2[f"err_r{a}_m"]), "k:", lw=1)
        ax[1].plot(t, 100 * np.array(s2[f"err_r{a}_m"]), label=a)
    ax[0].set(xlabel="t (s)", ylabel="m", title="relative CM position, LVLH (dotted: truth)")
    ax[1].set(xlabel="t (s)", ylabel="cm", title="position error")
    for a_ in ax:
        a_.legend(fontsize=7), a_.grid(alpha=.3)
    fig.savefig(HERE / "fig13_stage2_position.png", dpi=110)
    fig, ax = plt.subplots(1, 2, figsize=(9, 3.5), constrained_layout=True)
    for a in "xyz":
        ax[0].plot(t, s2[f"est_w{a}_deg_s"], label=f"ω{a} estimated")
        ax[0].plot(t, s2[f"true_w{a}_deg_s"], "k:", lw=1)
    ax[1].plot(t, s2["err_att_deg"])
    ax[0].set(xlabel="t (s)", ylabel="deg/s", title="body angular velocity (dotted: truth)")
    ax[1].set(xlabel="t (s)", ylabel="deg", title="attitude error (principal-axes frame)")
    for a_ in ax:
        a_.legend(fontsize=7) if a_ is ax[0] else None
        a_.grid(alpha=.3)
    fig.savefig(HERE / "fig14_stage2_attitude.png", dpi=110)
    plt.close("all")
    print(json.dumps(json.loads((HERE / "summary.json").read_text())["summary"], indent=1))


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--run", action="store_true")
    ap.add_argument("--analyse", action="store_true", help="re-analyse the truth set already in --work")
    ap.add_argument("--work", type=Path, default=Path("/tmp/renderlab_unknown_satellite"))
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    if args.run or args.analyse:
        run(args.work, args.seed, render=args.run)
    figures()
