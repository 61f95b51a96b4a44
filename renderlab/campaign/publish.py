"""Publish a campaign's raw tables as a study folder that regenerates its report with no re-run.

::

    RESULTS_DIR/
      campaign.json          the campaign manifest (plan: study, runs, seed, scenario; versions)
      runs.json              every run's status (ok / error, seconds, tables)
      tables/<name>.parquet  each table of all finished runs, concatenated in run order, as the study publishes it
                             (its ``publish_tables``: what its report reads; compact zstd, :mod:`.compact`)
      tables/raw_tables.json the full tables a reduction changed: SHA-256, rows, columns, how to regenerate them
      report/                made by ``renderlab report RESULTS_DIR`` from the tables above alone

:func:`renderlab.campaign.store.load_tables` and :func:`~renderlab.campaign.store.run_statuses` read this layout as
they read a live campaign folder, so every report function works on both (the readers of the layout —
``is_published``, ``load_published_tables``, ``published_statuses`` — live in the store; this module writes it).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from renderlab import plugins
from renderlab.campaign import compact, store
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


def published_tables(manifest: dict, tables: dict, tables_dir: Path) -> dict:
    """The tables the folder ships: the study's ``publish_tables`` of the campaign's tables (every table whole when
    the study has none); each full table it changes or drops is recorded in ``tables_dir/raw_tables.json``
    (:mod:`renderlab.campaign.compact`)."""
    study = manifest["plan"]["study"]
    reduce = getattr(plugins.studies.get(study), "publish_tables", None) if study in plugins.studies else None
    if reduce is None:
        return dict(tables)
    out = reduce(dict(tables))
    records = {name: compact.raw_record(t, compact.compact_bytes(t), recover=None,
                                        regenerate="the campaign command of README.md, then renderlab publish")
               for name, t in tables.items() if name not in out or not out[name].equals(t)}
    if records:
        (Path(tables_dir) / compact.RAW_TABLES).write_text(compact.raw_tables_json(records), encoding="utf-8")
    return out


def write_published(campaign_dir: Path, stage: Path, out_dir: Path, loaded: tuple) -> None:
    """Write the published files of ``campaign_dir`` (``loaded``: its :func:`renderlab.campaign.store.
    finished_campaign`) into the folder ``stage``, which becomes ``out_dir`` (``scenario_dir`` is made relative to
    ``out_dir``: the published files hold no absolute path)."""
    src, out = Path(campaign_dir), Path(out_dir)
    manifest, tables, statuses = loaded
    (stage / TABLES).mkdir()
    for name, t in sorted(published_tables(manifest, tables, stage / TABLES).items()):
        compact.write_compact(t, stage / TABLES / f"{name}.parquet")
    if isinstance(manifest.get("scenario_dir"), str):  # relative to the published folder, no absolute path
        scen = (src / manifest["scenario_dir"]).resolve()
        manifest = {**manifest, "scenario_dir": Path(os.path.relpath(scen, out.resolve())).as_posix()}
    (stage / "campaign.json").write_text(json.dumps(manifest, indent=1, sort_keys=True) + "\n", encoding="utf-8")
    slim = [{k: s.get(k) for k in ("run", "status", "error", "seconds", "tables") if k in s} for s in statuses]
    store.write_statuses(stage, manifest, slim)
