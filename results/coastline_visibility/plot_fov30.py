"""The 30 deg FOV row of the visibility variants side by side (reads the CSVs next to this file).

Usage: .venv/bin/python results/coastline_visibility/plot_fov30.py  → fov30_variants.png
"""

import csv
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

HERE = Path(__file__).parent
CASES = [("visibility.csv", "fraction_coast", "coastline in image (any lighting)"),
         ("epoch_2024-06-21/visibility.csv", "fraction_coast", "same, epoch 2024-06-21T10:00Z"),
         ("cadence_300s/visibility.csv", "fraction_coast", "same, one image every 5 min"),
         ("daylight/visibility.csv", "fraction_usable", "lit coastline (sun > 0 deg)"),
         ("daylight_clouds67/visibility.csv", "fraction_usable", "lit and cloud-free coastline (cover 0.67)")]

fig, ax = plt.subplots(figsize=(6.4, 4.2), constrained_layout=True)
for name, key, label in CASES:
    rows = [r for r in csv.DictReader(open(HERE / name)) if float(r["fov_deg"]) == 30.0]
    rows.sort(key=lambda r: float(r["inclination_deg"]))
    ax.plot([float(r["inclination_deg"]) for r in rows], [100 * float(r[key]) for r in rows], "o-", label=label)
ax.set_xlabel("inclination [deg]")
ax.set_ylabel("images [%]")
ax.set_ylim(0, 50)
ax.set_title("1000 km circular orbit, 30 deg FOV nadir camera, 24 h", fontsize=10)
ax.legend(fontsize=8)
fig.savefig(HERE / "fov30_variants.png", dpi=120)
