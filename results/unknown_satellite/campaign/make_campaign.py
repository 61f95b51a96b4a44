"""Unknown-satellite campaign results: publish a finished campaign's tables, figures and summary here, and
the Fisher-information table of the inertia ratios vs arc length.

    renderlab campaign scenes/microsat_campaign.toml --runs 20 --out /tmp/us_campaign --workers 0
    .venv/bin/python results/unknown_satellite/campaign/make_campaign.py --campaign /tmp/us_campaign \
        [--long-arc /tmp/us_long_arc]      # tables + figures + summary.csv + inertia_observability.csv
    .venv/bin/python results/unknown_satellite/campaign/make_campaign.py      # figures from the tables here

Everything here is regenerated from the Parquet tables (``scores``, ``stage2``, ``stage1_history``, ``points``,
``perturbations``; ``long_arc_*`` from the optional long-arc check campaign).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[2]
TABLES = ("scores", "stage2", "stage1_history", "points", "perturbations")


def publish(campaign: Path, long_arc: Path | None) -> None:
    import pyarrow.parquet as pq

    from renderlab.campaign.store import load_tables

    tables = load_tables(campaign)
    for name in TABLES:
        pq.write_table(tables[name], str(HERE / f"{name}.parquet"))
    if long_arc is not None:
        la = load_tables(long_arc)
        for name in ("scores", "stage2", "stage1_history"):
            pq.write_table(la[name], str(HERE / f"long_arc_{name}.parquet"))


def observability_table() -> None:
    from renderlab.scenario import load_scenario
    from renderlab.studies.unknown_satellite.figures import write_csv
    from renderlab.studies.unknown_satellite.observability import inertia_observability_table

    sc, _ = load_scenario(REPO / "scenes" / "unknown_satellite.toml")
    rows = inertia_observability_table(sc, progress=True).to_pylist()
    write_csv(HERE / "inertia_observability.csv", rows)


def figures() -> None:
    import csv

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import pyarrow.parquet as pq

    from renderlab.studies.unknown_satellite.figures import campaign_figures, score_summary, write_csv

    tables = {n: pq.read_table(str(HERE / f"{n}.parquet")) for n in TABLES if (HERE / f"{n}.parquet").is_file()}
    if "scores" in tables:
        campaign_figures(tables, HERE, prefix="")
        write_csv(HERE / "summary.csv", score_summary(tables["scores"]))
    if (HERE / "inertia_observability.csv").is_file():
        rows = list(csv.DictReader((HERE / "inertia_observability.csv").open()))
        fig, ax = plt.subplots(figsize=(6.5, 4), constrained_layout=True)
        for tag, mk in (("segments", "o"), ("ideal", "x")):
            for slow, col in ((False, "C0"), (True, "C3")):
                r = [x for x in rows if x["tracks"] == tag and ("slow" in x["label"]) == slow
                     and x["frames"] == "100"]
                if not r:
                    continue
                arc = np.array([float(x["arc_s"]) for x in r])
                s1 = np.array([float(x["sigma_ratio_12"]) for x in r])
                ax.loglog(arc, s1, mk + "-" if tag == "segments" else mk + ":", color=col,
                          label=f"σ(I1/I3), 100 frames, {'slow' if slow else 'default'} separation, {tag}")
        ax.axhline(0.1, color="k", lw=0.6, ls="--")
        ax.set(xlabel="arc length (s)", ylabel="CRLB σ of I1/I3 (σ_px = 0.3)",
               title="inertia ratios: Fisher information (eq. 7) vs arc")
        ax.legend(fontsize=6)
        ax.grid(alpha=0.3, which="both")
        fig.savefig(HERE / "inertia_sigma_vs_arc.png", dpi=110)
        plt.close(fig)
    if (HERE / "long_arc_scores.parquet").is_file():
        la = {n: pq.read_table(str(HERE / f"long_arc_{n}.parquet")) for n in ("scores", "stage2", "stage1_history")}
        write_csv(HERE / "long_arc_summary.csv", score_summary(la["scores"]))
        campaign_figures(la, HERE, prefix="long_arc_")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--campaign", type=Path, help="a finished `renderlab campaign` folder to publish")
    ap.add_argument("--long-arc", type=Path, help="the long-arc check campaign folder (optional)")
    ap.add_argument("--fim", action="store_true", help="recompute inertia_observability.csv (~1 min)")
    args = ap.parse_args()
    if args.campaign:
        publish(args.campaign, args.long_arc)
    if args.fim or args.campaign:
        observability_table()
    figures()
