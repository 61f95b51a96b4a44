"""HTML tables for reports: headers with units, numbers formatted, optional badge columns (jinja2-escaped text)."""

from __future__ import annotations

import html

from renderlab.report.style import fmt


def table(rows: list[dict], columns: list[tuple[str, str]], *, left: tuple[str, ...] = (),
          raw: tuple[str, ...] = ()) -> str:
    """``columns`` = [(key, header with unit), ...]; ``raw`` keys hold ready HTML (badges), others are escaped."""
    head = "".join(f'<th class="{"l" if k in left else ""}">{html.escape(h)}</th>' for k, h in columns)
    body = []
    for r in rows:
        cells = []
        for k, _ in columns:
            v = r.get(k, "")
            cells.append(f'<td class="{"l" if k in left else ""}">{v if k in raw else fmt(v)}</td>')
        body.append("<tr>" + "".join(cells) + "</tr>")
    return f"<table><tr>{head}</tr>{''.join(body)}</table>"


def plain_table(head, rows) -> str:
    """A bare ``<table>``: the header cells escaped, then one line per row of cells; a cell holding ``<`` is ready
    HTML (a badge) and kept, any other is escaped."""
    def cell(c) -> str:
        return c if isinstance(c, str) and "<" in c else html.escape(str(c))

    lines = ["<table><tr>" + "".join(f"<th>{html.escape(h)}</th>" for h in head) + "</tr>"]
    return "\n".join(lines + ["<tr>" + "".join(f"<td>{cell(c)}</td>" for c in r) + "</tr>" for r in rows]) + "</table>"
