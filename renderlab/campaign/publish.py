"""Publish a campaign's raw tables as a study folder that regenerates its report with no re-run.

::

    RESULTS_DIR/
      campaign.json          the campaign manifest (plan: study, runs, seed, scenario; versions)
      runs.json              every run's status (ok / error, seconds, tables)
      tables/<name>.parquet  each table of all finished runs, concatenated in run order (zstd)
      report/                made by ``renderlab report RESULTS_DIR`` from the tables above alone

:func:`renderlab.campaign.store.load_tables` and :func:`~renderlab.campaign.store.run_statuses` read this layout as
they read a live campaign folder, so every report function works on both.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from renderlab.errors import UserError

TABLES = "tables"
STATUSES = "runs.json"


def is_published(folder: Path) -> bool:
    """A published study folder (``tables/`` and ``runs.json`` beside ``campaign.json``, no ``runs/``)."""
    d = Path(folder)
    return (d / TABLES).is_dir() and (d / STATUSES).is_file() and not (d / "runs").is_dir()


def publish_campaign(campaign_dir: Path, out_dir: Path) -> Path:
    """Write ``campaign.json``, ``runs.json`` and ``tables/`` of ``campaign_dir`` into ``out_dir`` (atomically per
    file; other files of ``out_dir`` — README, report — are kept). Returns ``out_dir``."""
    import pyarrow.parquet as pq

    from renderlab.campaign import store

    src, out = Path(campaign_dir), Path(out_dir)
    manifest, tables, statuses = store.finished_campaign(src, "publish")
    with store.staged_folder(out, "the published study") as stage:
        (stage / TABLES).mkdir()
        for name, t in sorted(tables.items()):
            pq.write_table(t, str(stage / TABLES / f"{name}.parquet"), compression="zstd", compression_level=9)
        if isinstance(manifest.get("scenario_dir"), str):  # relative to the published folder, no absolute path
            scen = (src / manifest["scenario_dir"]).resolve()
            manifest = {**manifest, "scenario_dir": Path(os.path.relpath(scen, out.resolve())).as_posix()}
        (stage / "campaign.json").write_text(json.dumps(manifest, indent=1, sort_keys=True) + "\n", encoding="utf-8")
        slim = [{k: s.get(k) for k in ("run", "status", "error", "seconds", "tables") if k in s} for s in statuses]
        (stage / STATUSES).write_text(json.dumps(slim, indent=1) + "\n", encoding="utf-8")
    return out


def load_published_tables(folder: Path) -> dict:
    """``{name: pyarrow.Table}`` of a published folder (names are plain identifiers inside ``tables/``)."""
    import pyarrow.parquet as pq

    out = {}
    for p in sorted((Path(folder) / TABLES).glob("*.parquet")):
        if not p.stem.isidentifier() or p.is_symlink():
            raise UserError(f"{p}: published table names must be plain identifiers (no links)")
        try:
            out[p.stem] = pq.read_table(str(p))
        except (OSError, ValueError) as exc:
            raise UserError(f"cannot read {p}: {' '.join(str(exc).split())[:200]}") from None
    return out


def published_statuses(folder: Path) -> list[dict]:
    p = Path(folder) / STATUSES
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise UserError(f"cannot read {p}: {exc}") from None
    if not isinstance(data, list) or not all(isinstance(s, dict) and isinstance(s.get("run"), int) for s in data):
        raise UserError(f"{p}: must be a list of run statuses")
    return data
