"""CSV tables of reports (plain text a reviewer can diff): columns in order of first appearance, floats to 6 g."""

from __future__ import annotations

import csv
import io
from pathlib import Path


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
