"""``renderlab report CAMPAIGN_DIR [--out DIR] [--tables-only | --svg]`` (summary CSVs, figures and index.html from a campaign's tables; for a
registered result-folder kind — a ``renderlab crosscheck`` folder, an error budget — its own report from its
tables, :mod:`renderlab.contracts.result_folder`) and
``renderlab publish CAMPAIGN_DIR --out RESULTS_DIR`` (the raw tables as a study folder, then its report)."""

from __future__ import annotations

from pathlib import Path

from renderlab.errors import UserError


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("report", help="score a campaign (or a published study folder) and write summary "
                                             "CSVs, figures and an HTML page from its tables alone")
    p.add_argument("campaign", metavar="CAMPAIGN_DIR", help="folder made by renderlab campaign, renderlab publish or "
                                                               "renderlab crosscheck")
    p.add_argument("--out", metavar="DIR", help="report folder (files in it are replaced; default for a published "
                                                "study folder: CAMPAIGN_DIR/report)")
    p.add_argument("--tables-only", action="store_true",
                   help="write the CSV and text outputs only, no PNG/SVG figure: checks quickly that a published "
                        "folder's numbers follow from its tables")
    p.add_argument("--svg", action="store_true",
                   help="also write each figure as SVG beside its PNG, linked from the page (on demand: published "
                        "folders keep PNG only)")
    q = subparsers.add_parser("publish", help="copy a campaign's raw tables into a study folder (tables/*.parquet, "
                                              "campaign.json, runs.json) and write its report there")
    q.add_argument("campaign", metavar="CAMPAIGN_DIR", help="folder made by renderlab campaign")
    q.add_argument("--out", required=True, metavar="RESULTS_DIR", help="study folder (e.g. results/my_study)")
    q.set_defaults(command_module=__name__, publish=True)


def _result_folder_kind(folder: Path):
    """The first registered result-folder kind (:mod:`renderlab.contracts.result_folder`) that recognises
    ``folder``, else None (a campaign or published study folder)."""
    from renderlab.plugins import result_folders

    if not folder.is_dir():
        return None
    for name in result_folders.names():
        kind = result_folders.get(name)
        if kind.recognises(folder):
            return kind
    return None


def shown_as(out: Path) -> str:
    """How the published folder is named in its own report (no absolute path): as typed when relative, else relative
    to the current folder when inside it, else by its name (the command run from its parent folder)."""
    import os

    if not out.is_absolute():
        return out.as_posix()
    rel = os.path.relpath(out.resolve(), Path.cwd().resolve())
    return Path(rel).as_posix() if not rel.startswith("..") else out.name


def _publish(src: Path, out: Path) -> int:
    """``renderlab publish``: the tables and the report written into one stage, renamed into ``out`` together (an
    interrupted publish leaves no study without its report); the report names the folder as :func:`shown_as`."""
    from markupsafe import escape

    from renderlab.campaign import store
    from renderlab.campaign.publish import write_published
    from renderlab.report.campaign_report import make_report

    loaded = store.finished_campaign(src, "publish")  # validated before anything is created
    name = shown_as(out)
    with store.staged_folder(out, "the published study") as stage:
        write_published(src, stage, out, loaded)
        make_report(stage, stage / "report")
        for f in (stage / "report").iterdir():  # the stage's name → the study folder's, in the page and README
            if f.suffix in (".md", ".html") and f.is_file():
                text = f.read_text(encoding="utf-8")
                for old, new in ((stage.as_posix(), name), (str(escape(stage.as_posix())), str(escape(name)))):
                    text = text.replace(old, new)
                f.write_text(text, encoding="utf-8")
    print(f"renderlab: published {out} (tables/, campaign.json, runs.json); report {out / 'report' / 'index.html'}")
    return 0


def run(args) -> int:
    from renderlab.contracts.result_folder import tables_only, with_svg

    if getattr(args, "publish", False):
        return _publish(Path(args.campaign), Path(args.out))
    if getattr(args, "tables_only", False) and getattr(args, "svg", False):
        raise UserError("--svg draws figures and --tables-only draws none: give one of them")
    if getattr(args, "tables_only", False):
        with tables_only():
            return _report(args)
    if getattr(args, "svg", False):
        with with_svg():
            return _report(args)
    return _report(args)


def _report(args) -> int:
    """``renderlab report``: a registered result-folder kind's report, else the campaign report."""
    from renderlab.campaign.publish import is_published
    from renderlab.report.campaign_report import make_report

    src = Path(args.campaign)
    if not src.is_dir():
        raise UserError(f"{src} is not a campaign folder: no such folder (renderlab report reads a campaign, "
                        "published study or result folder)")
    kind = _result_folder_kind(src)
    if kind is not None:  # a registered result-folder kind: its report from its own tables
        files = kind.write_report(src, Path(args.out) if args.out else None)
        print(f"renderlab: wrote {', '.join(f.name for f in files)} into {files[0].parent}")
        return 0
    if args.out is None and not is_published(src):
        raise UserError("--out DIR is needed for a campaign folder (only a published study folder has a default)")
    page = make_report(src, Path(args.out) if args.out else src / "report")
    print(f"renderlab: wrote report {page}")
    return 0
