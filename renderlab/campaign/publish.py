"""Publish a campaign's raw tables as a study folder that regenerates its report with no re-run.

::

    RESULTS_DIR/
      campaign.json          the campaign manifest (plan: study, runs, seed, scenario; versions)
      runs.json              every run's status (ok / error, seconds, tables)
      tables/<name>.parquet  each table of all finished runs, concatenated in run order (zstd)
      report/                made by ``renderlab report RESULTS_DIR`` from the tables above alone

:func:`renderlab.campaign.store.load_tables` and :func:`~renderlab.campaign.store.run_statuses` read this layout as
they read a live campaign folder, so every report function works on both (the readers of the layout —
``is_published``, ``load_published_tables``, ``published_statuses`` — live in the store; this module writes it).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from renderlab.campaign import store
from renderlab.campaign.store import (  # noqa: F401
    STATUSES,
    TABLES,
    is_published,
    load_published_tables,
    published_statuses,  # the published layout is read by the store: re-exported
)


def publish_campaign(campaign_dir: Path, out_dir: Path) -> Path:
    """Write ``campaign.json``, ``runs.json`` and ``tables/`` of ``campaign_dir`` into ``out_dir`` through one stage
    (:func:`write_published`; other files of ``out_dir`` — README, report — are kept). Returns ``out_dir``."""
    loaded = store.finished_campaign(Path(campaign_dir), "publish")  # validated before anything is created
    with store.staged_folder(Path(out_dir), "the published study") as stage:
        write_published(campaign_dir, stage, Path(out_dir), loaded)
    return Path(out_dir)


def write_published(campaign_dir: Path, stage: Path, out_dir: Path, loaded: tuple) -> None:
    """Write the published files of ``campaign_dir`` (``loaded``: its :func:`renderlab.campaign.store.
    finished_campaign`) into the folder ``stage``, which becomes ``out_dir`` (``scenario_dir`` is made relative to
    ``out_dir``: the published files hold no absolute path)."""
    import pyarrow.parquet as pq

    src, out = Path(campaign_dir), Path(out_dir)
    manifest, tables, statuses = loaded
    (stage / TABLES).mkdir()
    for name, t in sorted(tables.items()):
        pq.write_table(t, str(stage / TABLES / f"{name}.parquet"), compression="zstd", compression_level=9)
    if isinstance(manifest.get("scenario_dir"), str):  # relative to the published folder, no absolute path
        scen = (src / manifest["scenario_dir"]).resolve()
        manifest = {**manifest, "scenario_dir": Path(os.path.relpath(scen, out.resolve())).as_posix()}
    (stage / "campaign.json").write_text(json.dumps(manifest, indent=1, sort_keys=True) + "\n", encoding="utf-8")
    slim = [{k: s.get(k) for k in ("run", "status", "error", "seconds", "tables") if k in s} for s in statuses]
    (stage / STATUSES).write_text(json.dumps(slim, indent=1) + "\n", encoding="utf-8")
