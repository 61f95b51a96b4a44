"""Example EV5 descent frames with landmark overlays, from a rendered truth set.

    .venv/bin/python -m renderlab render scenes/ev5_descent.toml --out OUT \
        --set 'trajectory.altitudes_m=[1000.0, 200.0, 50.0]'
    .venv/bin/python investigations/ev5_descent/make_figures.py OUT [--results DIR]

writes into ``results/ev5_descent/`` (``--results``) ``frame_<alt>m.png`` (sensor DN image; each landmark's maplet outline projected with the
true pose, coloured by tier; solid = visible, dashed = occluded; the label is gsd_ratio) and
``summary.csv`` (per frame and tier: in view, visible, occluded, median gsd_ratio, median shadow
fraction) and a copy of the truth set's ``landmark_truth.parquet``.
"""

from __future__ import annotations

import argparse
import csv
import json
import shutil
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
RESULT = REPO / "results" / "ev5_descent"
sys.path.insert(0, str(REPO))
COLORS = {"regional": "#ffb000", "approach": "#00d0ff", "site": "#ff4fd8"}


def main(truthset: str, out: Path = RESULT) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import pyarrow.parquet as pq
    from scipy.spatial.transform import Rotation

    from renderlab.files.imageio import read_dn_png
    from renderlab.geometry.camera import CameraModel
    from renderlab.worlds.ev5.catalog import read_catalog

    root = Path(truthset)
    manifest = json.loads((root / "manifest.json").read_text())
    maplets = {m.landmark_id: m for m in read_catalog(root)}
    lt = pq.read_table(str(root / "landmark_truth.parquet")).to_pydict()
    summary = []
    for frame in manifest["frames"]:
        cam = CameraModel.from_dict(frame["camera"])
        R = Rotation.from_quat(frame["pose"]["quat_render_from_cam_xyzw"]).as_matrix()
        t = np.array(frame["pose"]["position_m"])
        dn = read_dn_png(root / frame["dn"])
        alt = frame["ev5"]["altitude_m"]
        fig, ax = plt.subplots(figsize=(8, 8), dpi=110)
        ax.imshow(dn, cmap="gray", vmin=0, vmax=max(1, int(np.percentile(dn, 99.9))), interpolation="nearest")
        rows = [i for i, f in enumerate(lt["frame"]) if f == frame["index"]]
        per_tier: dict[str, list[int]] = {}
        for i in rows:
            per_tier.setdefault(lt["tier"][i], []).append(i)
            if not lt["in_view"][i]:
                continue
            m = maplets[lt["landmark_id"][i]]
            h = m.half_width_m
            edge = np.linspace(-h, h, 9)
            ring = np.concatenate([np.column_stack([edge, -h + 0 * edge]), np.column_stack([h + 0 * edge, edge]),
                                   np.column_stack([edge[::-1], h + 0 * edge]), np.column_stack([-h + 0 * edge, edge[::-1]])])
            outline = cam.project((m.to_body(np.column_stack([ring, np.zeros(len(ring))])) - t) @ R)
            color = COLORS.get(lt["tier"][i], "w")
            ax.plot(outline[:, 0], outline[:, 1], color=color, lw=1.0, ls="-" if lt["visible"][i] else "--")
            ax.plot(lt["s"][i], lt["l"][i], "+", color=color, ms=5)
            ax.annotate(f"{lt['gsd_ratio'][i]:.2f}", (lt["s"][i], lt["l"][i]), color=color, fontsize=6,
                        xytext=(3, 3), textcoords="offset points")
        ax.set_xlim(-0.5, dn.shape[1] - 0.5)
        ax.set_ylim(dn.shape[0] - 0.5, -0.5)
        gsd = float(np.linalg.norm(t - np.array(json.loads((root / "site.json").read_text())["origin_m"]))) / cam.fx
        ax.set_title(f"EV5 descent, altitude {alt:.0f} m, GSD {100 * gsd:.1f} cm at the site  "
                     f"(maplets: regional orange, approach cyan, site magenta; dashed = occluded; label = GSD/spacing)",
                     fontsize=7)
        ax.axis("off")
        fig.tight_layout()
        fig.savefig(out / f"frame_{alt:.0f}m.png")
        plt.close(fig)
        for tier, idx in sorted(per_tier.items()):
            view = [i for i in idx if lt["in_view"][i]]
            summary.append({"frame": frame["index"], "altitude_m": round(alt, 2), "tier": tier, "landmarks": len(idx),
                            "in_view": len(view), "visible": sum(lt["visible"][i] for i in idx),
                            "occluded": sum(lt["occluded"][i] for i in idx),
                            "median_gsd_ratio": round(float(np.median([lt["gsd_ratio"][i] for i in idx])), 3),
                            "median_shadow_fraction": round(float(np.median([lt["shadow_fraction"][i] for i in idx])), 3)})
    with open(out / "summary.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(summary[0]))
        w.writeheader()
        w.writerows(summary)
    shutil.copyfile(root / "landmark_truth.parquet", out / "landmark_truth.parquet")
    print(f"wrote {len(manifest['frames'])} figures, summary.csv and landmark_truth.parquet to {out}")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("truthset", metavar="OUT", help="the truth set renderlab render wrote")
    ap.add_argument("--results", type=Path, default=RESULT, help="folder of the figures (default: %(default)s)")
    args = ap.parse_args()
    main(args.truthset, args.results)
