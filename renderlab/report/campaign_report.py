"""``renderlab report CAMPAIGN_DIR --out DIR``: tables → CSV summaries, figures (PNG; SVG with ``--svg``) and one HTML
page. ``summary.csv`` holds the summary rows of every table (a ``table`` column says whose), written once.

Everything is recomputed from the campaign's Parquet tables (``runs/*/<table>.parquet``, or ``tables/<table>.parquet``
of a published study folder) by :mod:`renderlab.report.landmark_stats`, :mod:`renderlab.campaign.scoring` and the
study's own hooks; nothing is read from a previous report. The page is a jinja2 template
(``templates/report.html.j2``). Outputs are staged in a hidden sibling folder and moved into ``DIR`` file by file
once all are written.
"""

from __future__ import annotations

import os
from pathlib import Path

from renderlab import plugins
from renderlab.campaign import scoring, store
from renderlab.campaign.publish import is_published
from renderlab.contracts.observable import ReportContext
from renderlab.contracts.schemas import kind_of_table_name
from renderlab.report.csvio import write_csv  # noqa: F401  (re-exported for studies)
from renderlab.report.html_table import table as html_table

TEMPLATE_DIR = Path(__file__).parent / "templates"
#: a study section with this title opens the page (before the generic sections): what the numbers below measure
LEAD_TITLE = "What this campaign measures"


def make_report(campaign_dir: Path, out_dir: Path, *, confidence: float = 0.95) -> Path:
    """Write the report of ``campaign_dir`` into ``out_dir``; return the HTML page's path."""
    campaign_dir, out_dir = Path(campaign_dir), Path(out_dir)
    manifest, tables, statuses = store.finished_campaign(campaign_dir, "report")
    with store.staged_folder(out_dir, "the report") as stage:
        sections, summary, headline = _write_all(tables, stage, manifest, confidence)
        extra = _study_sections(manifest["plan"]["study"], tables, stage)
        sections = [x for x in extra if x["title"] == LEAD_TITLE] + sections \
            + [x for x in extra if x["title"] != LEAD_TITLE]
        regen = _regenerate_command(campaign_dir, out_dir)
        page = _page(manifest, statuses, sections, headline, regen)
        (stage / "index.html").write_text(page, encoding="utf-8")
        if summary:
            write_csv(stage / "summary.csv", summary)
        (stage / "README.md").write_text(
            f"# Campaign report: {manifest['name']}\n\nMade from the campaign's Parquet tables alone by (from the "
            f"folder that holds this report)\n\n    {regen}\n\nStudy `{manifest['plan']['study']}`, "
            f"{manifest['plan']['runs']} runs, seed {manifest['plan']['seed']['entropy']}. Open `index.html`.\n",
            encoding="utf-8")
    return out_dir / "index.html"


def _regenerate_command(campaign_dir: Path, out_dir: Path) -> str:
    """The command that remakes this report: a published study folder's default report needs only the folder."""
    if is_published(campaign_dir) and out_dir.resolve() == (campaign_dir / "report").resolve():
        return f"renderlab report {campaign_dir.as_posix()}"
    return f"renderlab report {_rel(campaign_dir, out_dir)} --out {out_dir.name}"


def _value_text(v) -> str:
    """A scenario value for people: lists comma-separated, tables as ``key = value``, no Python reprs."""
    if isinstance(v, dict):
        return ", ".join(f"{k} = {_value_text(x)}" for k, x in v.items())
    if isinstance(v, (list, tuple)):
        return ", ".join(_value_text(x) for x in v)
    return f"{v:g}" if isinstance(v, float) else str(v)


def _rel(campaign_dir: Path, out_dir: Path) -> str:
    """The campaign folder as seen from the folder that holds the report."""
    try:
        return Path(os.path.relpath(campaign_dir.resolve(), out_dir.resolve().parent)).as_posix()
    except ValueError:
        return str(campaign_dir)


def _study(name: str):
    return plugins.studies.get(name) if name in plugins.studies else None


def _study_sections(study: str, tables, stage: Path) -> list[dict]:
    """Extra sections from the registered study's ``report_sections(tables, out_dir) -> [(title, html)]``
    (optional; for tables the generic kinds do not cover). A study no longer registered gives none."""
    found = _study(study)
    hook = getattr(found, "report_sections", None)
    if not callable(hook):
        return []
    out = []
    for title, body in hook(tables, stage):
        out.append({"title": title, "anchor": title.lower().replace(" ", "-")[:40],
                    "blocks": [{"kind": "table", "html": body}]})
    return out


def _write_all(tables, stage: Path, manifest: dict, confidence) -> tuple[list[dict], list[dict], str]:
    """One section per table of a registered observable kind with a ``report_section`` (the registry
    :data:`renderlab.plugins.observables`; tables the study reports itself skipped), the summary rows and the
    headline (the first table's that gives one)."""
    sections, summary_all, headline = [], [], ""
    found = _study(manifest["plan"]["study"])
    context = ReportContext(study=found, scenario=manifest["plan"].get("scenario") or {}, confidence=confidence)
    for name, t in sorted(tables.items()):
        if name in getattr(found, "own_tables", ()):
            continue
        kind = kind_of_table_name(name) or scoring.table_kind(t)  # by name: a published table may be reduced
        report_section = None if kind == "other" else plugins.observable(kind).part("report_section")
        if report_section is None:
            continue
        sec, rows, head = report_section(name, t, stage, context)
        sections.append(sec)
        summary_all += rows
        headline = headline or head
    return sections, summary_all, headline


def _header_tables(manifest: dict) -> list[str]:
    plan = manifest["plan"]
    pert = [{"key": k, "value": _value_text(v)} for k, v in sorted((plan["scenario"].get("perturbations") or {}).items())
            if v not in (0, 0.0, [0.0] * 3, [0, 0, 0], {}, None)]
    ver = [{"key": k, "value": _value_text(v)} for k, v in sorted((manifest.get("versions") or {}).items())]
    out = []
    if pert:
        out.append("<h3>Perturbations (1σ, units in the key name)</h3>"
                   + html_table(pert, [("key", "scenario key"), ("value", "1σ")], left=("key", "value")))
    else:
        out.append("<p class='note'>No [perturbations] section: runs differ by their sensor noise and by what the study itself draws per run (its section below).</p>")
    if ver:
        out.append("<details><summary>Software versions</summary>"
                   + html_table(ver, [("key", "package"), ("value", "version")], left=("key", "value")) + "</details>")
    return out


def _environment():
    import jinja2

    return jinja2.Environment(loader=jinja2.FileSystemLoader(str(TEMPLATE_DIR)), autoescape=True)


def render_blocks(blocks: list[dict]) -> str:
    """HTML of a section's blocks (``{"kind": "text" | "h3" | "table" | "figure" | "links", ...}``), the way the
    report page renders them; for studies' own sections."""
    return _environment().get_template("blocks.html.j2").render(blocks=blocks)


def _page(manifest, statuses, sections, headline: str, regen: str) -> str:
    plan = manifest["plan"]
    counts: dict[str, int] = {}
    for s in statuses:
        counts[s["status"]] = counts.get(s["status"], 0) + 1
    return _environment().get_template("report.html.j2").render(
        title=f"Campaign {manifest['name']}",
        subtitle=(f"Study {plan['study']}, {plan['runs']} runs ("
                  + ", ".join(f"{v} {k}" for k, v in sorted(counts.items()))
                  + f"), root seed {plan['seed']['entropy']}; run i is seeded by {plan['seed']['run_seed']}."),
        headline=headline, header_tables=_header_tables(manifest), regenerate=regen,
        failed=[s for s in statuses if s["status"] == "error"][:10], sections=sections)
