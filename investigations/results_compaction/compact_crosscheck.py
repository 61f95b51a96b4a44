"""Compact the published cross-renderer checks (``results/crosscheck/<scene>``, a result-folder kind, not a campaign)
in place with :func:`renderlab.campaign.compact.compact_folder`: ``crosscheck.parquet`` whole, and of
``crosscheck_images.parquet`` the columns the report reads (:func:`renderlab.crosscheck.figures.read_images`:
``frame``, ``height``, ``width`` and the four float32 images; ``time_s`` is read from ``crosscheck.parquet``); both
written by the compact writer, the full images table recorded in the folder's ``raw_tables.json``.

    .venv/bin/python investigations/results_compaction/compact_crosscheck.py [--root ROOT]

``ROOT`` holds the ``results/`` folder (default: the repository); a copy under /tmp is where to try it first.
Nothing lossy is possible here: the images are float32 as rendered (the radiances are the truth sets' float32
AOVs), ``gap_px`` comes from the two renderers' hit points and ``shadow_shift_px`` from their ids and normals, none
of which the folder holds, so only the encoding and the unread ``time_s`` column go.
"""

from __future__ import annotations

import argparse
from pathlib import Path

SCENES = ("analytic_sphere_box", "ev5_low_sun", "ev5_small_descent")
COMMAND = "the renderlab crosscheck command of results/crosscheck/README.md for this folder"


def transform(tables: dict) -> dict:
    """The published tables of one crosscheck folder (module docstring)."""
    from renderlab.campaign.compact import keep_columns
    from renderlab.crosscheck.figures import IMAGE_COLUMNS, IMAGES

    return keep_columns(tables, {Path(IMAGES).stem: ("frame", "height", "width", *IMAGE_COLUMNS.values())})


def main(argv: list[str] | None = None) -> int:
    from renderlab.campaign.compact import compact_folder

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--root", type=Path, default=Path(__file__).resolve().parents[2],
                    help="folder holding results/ (default: the repository)")
    args = ap.parse_args(argv)
    for scene in SCENES:
        folder = args.root / "results" / "crosscheck" / scene
        sizes = compact_folder(folder, transform, tables_dir=".", command=COMMAND)
        for name, (a, b) in sorted(sizes.items()):
            print(f"results/crosscheck/{scene}/{name}.parquet: {a} -> {b} bytes")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
