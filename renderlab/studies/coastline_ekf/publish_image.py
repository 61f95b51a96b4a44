"""Publish the image-in-the-loop coastline campaign beside the paper's idealised (geometric) measurements.

    python -m renderlab.studies.coastline_ekf.publish_image --runs 8 --work out/coastline_image \\
        --out results/coastline_ekf/image_in_the_loop

(``--truth-cache OTHER_WORK/work/truth_cache`` reuses another variant's renders.)

1. ``renderlab campaign scenes/coastline_image.toml --runs N --out WORK`` (rendered frames → extraction →
   matching → LOS → EKF; seeded, resumable) and ``renderlab report WORK --out OUT/report``.
2. The same scenario in geometric mode (``coastline.mode = "geometric"``, same orbit, times, σθ, P0, star
   tracker, seeds): LOS to the visible database points plus σθ noise, exactly what the filter assumes.
3. ``comparison.png`` (RIC position error RMS and filter σ, ANEES with its 99 % band, both modes),
   ``comparison.csv`` (per mode: final RMS and filter σ per axis, mean ANEES, NIS total / dof),
   the runs' tables ``coastline_filter.parquet`` / ``coastline_frames.parquet`` (image mode) and the frames'
   ``contact_sheet.png``.
"""

from __future__ import annotations

import argparse
import csv
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np


def _mpl():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _mode_summary(name: str, table) -> dict:
    from renderlab.studies.coastline_ekf.scoring import chi2_band, nis_total_test, per_time_summary

    s = per_time_summary(table)
    n = int(s["n_runs"].to_numpy()[0])
    row = {"mode": name, "runs": n, "images": int(len(s) - 1), "los_per_image_mean": float(np.mean(s["n_meas"].to_numpy()[1:]))}
    for a, u, scale, unit in (("r", "m", 1, "m"), ("i", "m", 1, "m"), ("c", "m", 1, "m"),
                              ("vr", "mps", 1e3, "mmps"), ("vi", "mps", 1e3, "mmps"), ("vc", "mps", 1e3, "mmps")):
        row[f"final_rms_{a}_{unit}"] = float(s[f"mc_rms_{a}_{u}"].to_numpy()[-1] * scale)
        row[f"final_filter_sig_{a}_{unit}"] = float(s[f"filter_sig_{a}_{u}"].to_numpy()[-1] * scale)
    lo, hi = chi2_band(6.0, n)
    anees = s["anees"].to_numpy()
    row["anees_final"] = float(anees[-1])
    row["anees_99_band"] = f"[{float(lo):.2f}, {float(hi):.2f}]"
    row["anees_inside_99_fraction"] = float(np.mean((anees >= lo) & (anees <= hi)))
    row["anees_by_time"] = " ".join(f"{v:.1f}" for v in anees)      # prior, then one value per image
    nis = nis_total_test(table)
    row["nis_total_over_dof"] = nis["ratio"]
    row["nis_total_inside_99"] = nis["inside"]
    return row, s


def _figure(summaries: dict, path: Path) -> None:
    plt = _mpl()
    fig, axs = plt.subplots(1, 4, figsize=(16, 3.8))
    colors = {"geometric": "tab:blue", "image": "tab:red"}
    for mode, s in summaries.items():
        t = s["t_s"].to_numpy() - s["t_s"].to_numpy()[0]
        for ax, (a, label) in zip(axs[:3], (("r", "radial"), ("i", "in-track"), ("c", "cross-track"))):
            ax.plot(t, s[f"mc_rms_{a}_m"].to_numpy(), "-", color=colors[mode], label=f"{mode}: MC RMS")
            ax.plot(t, s[f"filter_sig_{a}_m"].to_numpy(), "--", color=colors[mode], label=f"{mode}: filter σ")
            ax.set_title(f"{label} position error [m]")
            ax.set_xlabel("time since prior [s]")
        axs[3].semilogy(t, s["anees"].to_numpy(), "o-", ms=3, color=colors[mode], label=f"{mode} ANEES")
        axs[3].fill_between(t, s["anees_lo"].to_numpy(), s["anees_hi"].to_numpy(), color=colors[mode], alpha=0.15)
    axs[3].set_title("ANEES (6 dof) with 99 % χ² band")
    axs[3].set_xlabel("time since prior [s]")
    for ax in axs:
        ax.grid(alpha=0.3)
    axs[0].legend(fontsize=7)
    axs[3].legend(fontsize=7)
    fig.suptitle("Coastline EKF: idealised LOS (geometric, the paper's simulation) vs rendered images "
                 "(extraction + matching + map error + clouds), same orbit, times, σθ, P0 and seeds", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    import pyarrow.parquet as pq

    from renderlab.campaign import store
    from renderlab.campaign.plan import run_seed_sequence
    from renderlab.campaign.runner import run_campaign_file
    from renderlab.report.campaign_report import make_report
    from renderlab.scenario import load_scenario
    from renderlab.studies.coastline_ekf.geometric import run_batch
    from renderlab.studies.coastline_ekf.study import geometric_options

    p = argparse.ArgumentParser(prog="python -m renderlab.studies.coastline_ekf.publish_image", description=__doc__.split("\n")[0])
    p.add_argument("--scenario", type=Path, default=Path("scenes/coastline_image.toml"))
    p.add_argument("--runs", type=int, default=8)
    p.add_argument("--work", type=Path, required=True, help="campaign folder (renders, runs)")
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--set", dest="overrides", action="append", default=[])
    p.add_argument("--truth-cache", type=Path, default=None,
                   help="reuse the renders of another campaign's WORK/work/truth_cache (same rendered scenario; "
                        "the cache is keyed by the render scenario, so a mismatch renders anew)")
    args = p.parse_args(argv)
    if args.truth_cache is not None and not (args.work / store.MANIFEST).is_file():
        from renderlab.campaign.plan import make_plan

        sc0, base0 = load_scenario(args.scenario, args.overrides)
        store.open_campaign(args.work, make_plan(sc0, base0, args.runs), resume=False)
        (args.work / "work").mkdir(exist_ok=True)
        (args.work / "work" / "truth_cache").symlink_to(args.truth_cache.resolve(), target_is_directory=True)
    run_campaign_file(args.scenario, args.work, args.runs, overrides=args.overrides, workers=0,
                      resume=(args.work / store.MANIFEST).is_file())
    args.out.mkdir(parents=True, exist_ok=True)
    make_report(args.work, args.out / "report")
    tables = store.load_tables(args.work)
    img = tables["coastline_filter"]
    pq.write_table(img, args.out / "coastline_filter.parquet")
    pq.write_table(tables["coastline_frames"], args.out / "coastline_frames.parquet")
    sheets = sorted((args.work / "work" / "truth_cache").glob("*/contact_sheet.png"))
    if sheets:
        shutil.copyfile(sheets[0], args.out / "contact_sheet.png")
    sc, _ = load_scenario(args.scenario, args.overrides)
    tr = sc.trajectory
    geo_sc = sc.model_copy(update={"coastline": sc.coastline.model_copy(update={"mode": "geometric"})})
    o = replace(geometric_options(geo_sc), duration_s=tr.frames * tr.dt_s).validate()
    seeds = [run_seed_sequence(sc.campaign.seed, i) for i in range(args.runs)]
    geo = run_batch(o, seeds)["table"]
    pq.write_table(geo, args.out / "geometric_filter.parquet")
    rows, summaries = [], {}
    for name, t in (("geometric", geo), ("image", img.drop(["campaign"]) if "campaign" in img.column_names else img)):
        row, s = _mode_summary(name, t)
        rows.append(row)
        summaries[name] = s
    fr = tables["coastline_frames"]
    los = fr["los_err_px_median"].to_numpy()
    rows[1]["los_err_px_median_over_images"] = float(np.nanmedian(los))
    rows[1]["images_without_match_fraction"] = float(np.mean(fr["n_matched"].to_numpy() == 0))
    with open(args.out / "comparison.csv", "w", newline="") as f:
        cols = list(dict.fromkeys(k for r in rows for k in r))
        w = csv.DictWriter(f, fieldnames=cols, lineterminator="\n")
        w.writeheader()
        w.writerows(rows)
    _figure(summaries, args.out / "comparison.png")
    print((args.out / "comparison.csv").read_text())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
