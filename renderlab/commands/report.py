"""``renderlab report CAMPAIGN_DIR [--out DIR]`` (summary CSVs, figures and index.html from a campaign's tables; for a
``renderlab crosscheck`` folder its crosscheck.md and figure from its two tables, into the folder by default) and
``renderlab publish CAMPAIGN_DIR --out RESULTS_DIR`` (the raw tables as a study folder, then its report)."""

from __future__ import annotations

from pathlib import Path


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("report", help="score a campaign (or a published study folder) and write summary "
                                             "CSVs, figures and an HTML page from its tables alone")
    p.add_argument("campaign", metavar="CAMPAIGN_DIR", help="folder made by renderlab campaign, renderlab publish or "
                                                               "renderlab crosscheck")
    p.add_argument("--out", metavar="DIR", help="report folder (files in it are replaced; default for a published "
                                                "study folder: CAMPAIGN_DIR/report)")
    q = subparsers.add_parser("publish", help="copy a campaign's raw tables into a study folder (tables/*.parquet, "
                                              "campaign.json, runs.json) and write its report there")
    q.add_argument("campaign", metavar="CAMPAIGN_DIR", help="folder made by renderlab campaign")
    q.add_argument("--out", required=True, metavar="RESULTS_DIR", help="study folder (e.g. results/my_study)")
    q.set_defaults(command_module=__name__, publish=True)


def run(args) -> int:
    from renderlab.campaign.publish import is_published, publish_campaign
    from renderlab.errors import UserError
    from renderlab.report.campaign_report import make_report

    if getattr(args, "publish", False):
        out = publish_campaign(Path(args.campaign), Path(args.out))
        page = make_report(out, out / "report")
        print(f"renderlab: published {out} (tables/, campaign.json, runs.json); report {page}")
        return 0
    src = Path(args.campaign)
    from renderlab.crosscheck_figures import is_crosscheck_folder, write_report

    if is_crosscheck_folder(src):  # a renderlab crosscheck folder: its page and figure from its two tables
        files = write_report(src, Path(args.out) if args.out else src)
        print(f"renderlab: wrote {', '.join(f.name for f in files)} into {files[0].parent}")
        return 0
    if args.out is None and not is_published(src):
        raise UserError("--out DIR is needed for a campaign folder (only a published study folder has a default)")
    page = make_report(src, Path(args.out) if args.out else src / "report")
    print(f"renderlab: wrote report {page}")
    return 0
