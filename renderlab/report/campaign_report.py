"""``renderlab report CAMPAIGN_DIR --out DIR``: tables → summary.csv, figures and an HTML page.

Everything is recomputed from the campaign's Parquet tables (``runs/*/<table>.parquet``) by
:mod:`renderlab.campaign.scoring`; nothing is read from a previous report. Outputs are staged in a
hidden sibling folder and moved into ``DIR`` file by file once all are written.
"""

from __future__ import annotations

import csv
import html
import io
import os
import secrets
import shutil
from pathlib import Path

import numpy as np

from renderlab.errors import UserError


def write_csv(path: Path, rows: list[dict]) -> None:
    """Rows (dicts) → CSV, columns in order of first appearance, floats to 6 significant digits."""
    cols: list[str] = []
    for r in rows:
        cols += [k for k in r if k not in cols]
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=cols, lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})
    Path(path).write_text(buf.getvalue(), encoding="utf-8")


def _html_table(rows: list[dict], cols: list[str]) -> str:
    def fmt(v):
        return f"{v:.4g}" if isinstance(v, float) else html.escape(str(v))
    head = "".join(f"<th>{html.escape(c)}</th>" for c in cols)
    body = "".join("<tr>" + "".join(f"<td>{fmt(r.get(c, ''))}</td>" for c in cols) + "</tr>" for r in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


def _ci(r, key):
    return f"{r[key]:+.4f} [{r[key + '_lo']:+.4f}, {r[key + '_hi']:+.4f}]"


def make_report(campaign_dir: Path, out_dir: Path, *, confidence: float = 0.95) -> Path:
    """Write the report of ``campaign_dir`` into ``out_dir``; return the HTML page's path."""
    from renderlab.campaign import scoring, store
    from renderlab.report import campaign_figures as figs

    campaign_dir, out_dir = Path(campaign_dir), Path(out_dir)
    manifest = store.read_manifest(campaign_dir)
    tables = store.load_tables(campaign_dir)
    statuses = store.run_statuses(campaign_dir)
    if not tables:
        raise UserError(f"campaign {campaign_dir} has no finished runs to report")
    if out_dir.exists() and not out_dir.is_dir():
        raise UserError(f"--out {out_dir} exists and is not a directory")
    out_dir.parent.mkdir(parents=True, exist_ok=True)
    stage = out_dir.parent / f".{out_dir.name}.staging-{os.getpid()}-{secrets.token_hex(4)}"
    stage.mkdir()
    try:
        sections = _write_all(tables, stage, confidence, scoring, figs)
        sections += _study_sections(manifest["plan"]["study"], tables, stage)
        page = _page(manifest, statuses, sections, campaign_dir, out_dir)
        (stage / "index.html").write_text(page, encoding="utf-8")
        (stage / "README.md").write_text(
            f"# Campaign report: {manifest['name']}\n\nMade from the campaign's Parquet tables by\n\n"
            f"    renderlab report {campaign_dir.name} --out {out_dir.name}\n\n"
            f"Study `{manifest['plan']['study']}`, {manifest['plan']['runs']} runs, seed "
            f"{manifest['plan']['seed']['entropy']}. Open `index.html`.\n", encoding="utf-8")
        out_dir.mkdir(exist_ok=True)
        for f in sorted(stage.iterdir()):
            os.replace(f, out_dir / f.name)
    finally:
        shutil.rmtree(stage, ignore_errors=True)
    return out_dir / "index.html"


def _study_sections(study: str, tables, stage: Path) -> list[tuple[str, str]]:
    """Extra sections from the registered study's ``report_sections(tables, out_dir) -> [(title, html)]``
    (optional; for tables the generic kinds do not cover). A study no longer registered gives none."""
    from renderlab import plugins

    if study not in plugins.studies:
        return []
    hook = plugins.studies.get(study).report_sections
    return list(hook(tables, stage)) if callable(hook) else []


def _write_all(tables, stage: Path, confidence, scoring, figs) -> list[tuple[str, str]]:
    """Scores, CSVs and figures of every table; returns HTML sections (title, body)."""
    sections, summary_all = [], []
    for name, t in sorted(tables.items()):
        kind = scoring.table_kind(t)
        if kind == "landmark":
            rows = [{"table": name, **r} for r in scoring.score_measurements(t, confidence)]
            summary_all += rows
            brk = [r for col in scoring.BREAKDOWNS for r in scoring.breakdown(t, col, confidence=confidence)]
            write_csv(stage / f"{name}_breakdown.csv", brk)
            pre = f"{name}_"
            figs.scatter(t, stage / f"{pre}scatter.png")
            figs.fractional_shift(t, stage / f"{pre}fractional_shift.png")
            figs.failures(rows, stage / f"{pre}failures.png")
            figs.crlb_ratio(rows, stage / f"{pre}crlb_ratio.png")
            has_brk = figs.breakdowns(brk, stage / f"{pre}breakdowns.png")
            lines = [f"<li>{html.escape(r['method'])} {r['axis']}: bias {_ci(r, 'mean')} px, noise σ "
                     f"{r['std']:.4f} [{r['std_lo']:.4f}, {r['std_hi']:.4f}] px, median {_ci(r, 'median')}, "
                     f"MAD {r['mad']:.4f}, no result {100 * r['no_result_rate']:.1f} % "
                     f"[{100 * r['no_result_lo']:.1f}, {100 * r['no_result_hi']:.1f}]"
                     + (f", noise/CRLB {r['std_over_crlb']:.3g}" if np.isfinite(r.get("std_over_crlb", np.nan)) else "")
                     + "</li>" for r in rows]
            imgs = ["scatter", "fractional_shift", "failures", "crlb_ratio"] + (["breakdowns"] if has_brk else [])
            body = (f"<p>{confidence:.0%} confidence intervals in brackets (bias: Student t; noise: χ²; median: "
                    "order statistics; no-result rate: Wilson).</p><ul>" + "".join(lines) + "</ul>"
                    + "".join(f'<p><img src="{pre}{i}.png" alt="{i}"></p>' for i in imgs)
                    + f'<p>Breakdown table: <a href="{name}_breakdown.csv">{name}_breakdown.csv</a></p>')
            sections.append((f"Measurements: {name}", body))
        elif kind == "filter":
            rows = scoring.score_filter(t, confidence=confidence)
            write_csv(stage / f"{name}_filter_summary.csv", rows)
            figs.filter_errors(t, stage / f"{name}_errors.png")
            cols = sorted({k for r in rows for k in r}, key=lambda k: list(rows[0]).index(k) if k in rows[0] else 99)
            sections.append((f"Filter: {name}", _html_table(rows, cols) + f'<p><img src="{name}_errors.png"></p>'))
    if summary_all:
        write_csv(stage / "summary.csv", summary_all)
    return sections


def _page(manifest, statuses, sections, campaign_dir: Path, out_dir: Path) -> str:
    plan = manifest["plan"]
    counts: dict[str, int] = {}
    for s in statuses:
        counts[s["status"]] = counts.get(s["status"], 0) + 1
    errors = [s for s in statuses if s["status"] == "error"][:10]
    pert = {k: v for k, v in plan["scenario"].get("perturbations", {}).items() if v not in (0, 0.0, [0.0] * 3, {}, None)}
    parts = [
        "<!doctype html><html><head><meta charset='utf-8'>",
        f"<title>renderlab campaign {html.escape(manifest['name'])}</title>",
        "<style>body{font-family:sans-serif;max-width:1200px;margin:2em auto}table{border-collapse:collapse}"
        "td,th{border:1px solid #ccc;padding:2px 6px;font-size:12px}img{max-width:100%}</style></head><body>",
        f"<h1>Campaign {html.escape(manifest['name'])}</h1>",
        f"<p>Study <b>{html.escape(plan['study'])}</b>, {plan['runs']} runs, root seed {plan['seed']['entropy']} "
        f"(run i: {html.escape(plan['seed']['run_seed'])}). Runs: "
        + ", ".join(f"{v} {k}" for k, v in sorted(counts.items())) + ".</p>",
        f"<p>Perturbations (1σ): <code>{html.escape(str(pert) if pert else 'none')}</code></p>",
        f"<p>Versions: <code>{html.escape(str(manifest.get('versions', {})))}</code></p>",
        f"<p>Regenerate: <code>renderlab report {html.escape(campaign_dir.name)} --out {html.escape(out_dir.name)}"
        "</code>. Summary: <a href='summary.csv'>summary.csv</a>.</p>",
    ]
    if errors:
        parts.append("<h2>Failed runs</h2><ul>" + "".join(
            f"<li>run {s['run']}: {html.escape(s.get('error', ''))}</li>" for s in errors) + "</ul>")
    for title, body in sections:
        parts.append(f"<h2>{html.escape(title)}</h2>{body}")
    parts.append("</body></html>")
    return "\n".join(parts)
