"""``renderlab report CAMPAIGN_DIR --out DIR``: summary.csv, figures and index.html from a campaign's tables."""

from __future__ import annotations

from pathlib import Path


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("report", help="score a campaign and write summary.csv, figures and an HTML page")
    p.add_argument("campaign", metavar="CAMPAIGN_DIR", help="folder made by renderlab campaign")
    p.add_argument("--out", required=True, metavar="DIR", help="report folder (files in it are replaced)")


def run(args) -> int:
    from renderlab.report.campaign_report import make_report

    page = make_report(Path(args.campaign), Path(args.out))
    print(f"renderlab: wrote report {page}")
    return 0
