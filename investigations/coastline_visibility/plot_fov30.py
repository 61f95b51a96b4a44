"""The 30 deg FOV row of the visibility variants side by side, from the CSVs of ``results/coastline_visibility``.

Usage: .venv/bin/python investigations/coastline_visibility/plot_fov30.py [--results DIR]  → DIR/fov30_variants.png
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

RESULT = Path(__file__).resolve().parents[2] / "results" / "coastline_visibility"
CASES = [("visibility.csv", "fraction_coast", "coastline in image (any lighting)"),
         ("epoch_2024-06-21/visibility.csv", "fraction_coast", "same, epoch 2024-06-21T10:00Z"),
         ("cadence_300s/visibility.csv", "fraction_coast", "same, one image every 5 min"),
         ("daylight/visibility.csv", "fraction_usable", "lit coastline (sun > 0 deg)"),
         ("daylight_clouds67/visibility.csv", "fraction_usable", "lit and cloud-free coastline (cover 0.67)")]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--results", type=Path, default=RESULT, help="the visibility folder (default: %(default)s)")
    args = ap.parse_args(argv)

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.2), constrained_layout=True)
    for name, key, label in CASES:
        with open(args.results / name) as fh:
            rows = [r for r in csv.DictReader(fh) if float(r["fov_deg"]) == 30.0]
        rows.sort(key=lambda r: float(r["inclination_deg"]))
        ax.plot([float(r["inclination_deg"]) for r in rows], [100 * float(r[key]) for r in rows], "o-", label=label)
    ax.set_xlabel("inclination [deg]")
    ax.set_ylabel("images [%]")
    ax.set_ylim(0, 50)
    ax.set_title("1000 km circular orbit, 30 deg FOV nadir camera, 24 h", fontsize=10)
    ax.legend(fontsize=8)
    fig.savefig(args.results / "fov30_variants.png", dpi=120)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
