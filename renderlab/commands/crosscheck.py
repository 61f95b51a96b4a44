"""``renderlab crosscheck``: render a scenario with Mitsuba and Cycles and report their agreement."""

from __future__ import annotations

import argparse
from pathlib import Path

from renderlab.commands import cost
from renderlab.commands.cost import load_checked


def _pos_int(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return v


def add_parser(sub) -> None:
    p = sub.add_parser("crosscheck", help="render a scenario with Mitsuba and Cycles and compare the truth")
    p.add_argument("scenario", metavar="SCENARIO", help="scenario TOML file (see scenes/)")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="output folder: crosscheck.parquet, crosscheck.md, crosscheck.png")
    p.add_argument("--frames", type=_pos_int, metavar="N", help="only the first N frames")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", dest="overrides",
                   help="override a scenario key (TOML value), e.g. --set camera.width=128; repeatable")
    p.add_argument("--keep-truthsets", action="store_true", help="keep both truth sets in DIR/truthsets/")
    p.add_argument("--allow-large", action="store_true",
                   help="run past the cost limits (pixels × spp × frames of both renders, memory, disk)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def run(args) -> int:
    from renderlab.commands.inputs import check_scenario_inputs

    scenario, base = load_checked(args.scenario, args.overrides)
    check_scenario_inputs(scenario, base)
    cost.check_scenario(scenario, frames=args.frames, renders=2, out=args.out, allow_large=args.allow_large,
                        what=f"crosscheck of {Path(args.scenario).name}")
    from renderlab.crosscheck import TARGETS, run_crosscheck

    rows = run_crosscheck(scenario, base, Path(args.out), frames=args.frames,
                          keep_truthsets=args.keep_truthsets, progress=not args.quiet)
    import numpy as np

    worst = {k: (float(np.nanmax(v)) if np.isfinite(v := np.array([getattr(r, k) for r in rows], float)).any()
                 else float("nan")) for k in TARGETS}
    print(f"renderlab: crosscheck of {len(rows)} frames → {Path(args.out) / 'crosscheck.md'}; worst frame: "
          f"radiometric median {worst['rad_median_rel'] * 100:.4f} %, geometric {worst['geo_max_px']:.4f} px, "
          f"shadow-edge p99 {worst['shadow_p99_px']:.3f} px")
    return 0
