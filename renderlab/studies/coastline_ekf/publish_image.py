"""Publish the image-in-the-loop coastline campaign beside the paper's idealised (geometric) measurements: the
campaign (``renderlab campaign``, then ``renderlab publish``), the same scenario in geometric mode as
``geometric_filter``, the frames' ``contact_sheet.png``; ``--variant NAME`` adds a campaign's tables as
``variant_NAME_{filter,frames}``; ``--truth-cache`` reuses another campaign's renders. The commands of the published
folder: results/coastline_ekf/image_in_the_loop/README.md.
"""

from __future__ import annotations

import argparse
import shutil
from dataclasses import replace
from pathlib import Path

from renderlab.campaign import store
from renderlab.campaign.compact import compact_folder, write_compact
from renderlab.campaign.plan import make_plan, run_seed_sequence
from renderlab.campaign.publish import is_published, publish_campaign
from renderlab.campaign.runner import run_campaign_file
from renderlab.errors import UserError, run_main
from renderlab.report.campaign_report import make_report
from renderlab.scenario import load_scenario
from renderlab.studies.coastline_ekf.geometric import run_batch
from renderlab.studies.coastline_ekf.publish import publish_tables
from renderlab.studies.coastline_ekf.study import geometric_options


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m renderlab.studies.coastline_ekf.publish_image",
                                description=__doc__.split("\n")[0])
    p.add_argument("--scenario", type=Path, default=Path("scenes/coastline_image.toml"))
    p.add_argument("--runs", type=int, default=8)
    p.add_argument("--work", type=Path, required=True, help="campaign folder (renders, runs)")
    p.add_argument("--out", type=Path, required=True, help="published study folder")
    p.add_argument("--set", dest="overrides", action="append", default=[])
    p.add_argument("--variant", default=None, help="publish this campaign as variant NAME of the folder --out")
    p.add_argument("--truth-cache", type=Path, default=None,
                   help="reuse the renders of another campaign's WORK/work/truth_cache")
    return p


def _geometric(args) -> object:
    """The scenario in geometric mode with the campaign's seeds → its filter table."""
    sc, _ = load_scenario(args.scenario, args.overrides)
    tr = sc.trajectory
    geo_sc = sc.model_copy(update={"coastline": sc.coastline.model_copy(update={"mode": "geometric"})})
    o = replace(geometric_options(geo_sc), duration_s=tr.frames * tr.dt_s).validate()
    return run_batch(o, [run_seed_sequence(sc.campaign.seed, i) for i in range(args.runs)])["table"]


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    if args.variant is not None and not (args.variant.isidentifier() and is_published(args.out)):
        raise UserError(f"--variant {args.variant!r} needs an identifier and an already published --out folder "
                        "(publish the main campaign there first)")
    if args.truth_cache is not None and not (args.work / store.MANIFEST).is_file():
        sc0, base0 = load_scenario(args.scenario, args.overrides)
        store.open_campaign(args.work, make_plan(sc0, base0, args.runs), resume=False)
        (args.work / "work").mkdir(exist_ok=True)
        (args.work / "work" / "truth_cache").symlink_to(args.truth_cache.resolve(), target_is_directory=True)
    run_campaign_file(args.scenario, args.work, args.runs, overrides=args.overrides, workers=0,
                      resume=(args.work / store.MANIFEST).is_file())
    if args.variant is None:
        publish_campaign(args.work, args.out)
        write_compact(_geometric(args), args.out / "tables" / "geometric_filter.parquet")
        sheets = sorted((args.work / "work" / "truth_cache").glob("*/contact_sheet.png"))
        if sheets:
            shutil.copyfile(sheets[0], args.out / "contact_sheet.png")
    else:
        tables = store.load_tables(args.work)
        for kind in ("filter", "frames"):
            write_compact(tables[f"coastline_{kind}"], args.out / "tables" / f"variant_{args.variant}_{kind}.parquet")
    compact_folder(args.out, publish_tables, command="the publish_image commands of README.md")
    page = make_report(args.out, args.out / "report")
    print((args.out / "report" / "comparison.csv").read_text())
    print(f"published {args.out}; report {page}")
    return 0


if __name__ == "__main__":
    raise SystemExit(run_main(main))
