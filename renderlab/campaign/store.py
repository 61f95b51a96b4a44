"""The campaign folder: manifest, one result folder per finished run, written atomically.

::

    CAMPAIGN_DIR/
      campaign.json            format, plan (study, runs, seed, scenario), versions
      runs/000000/             one folder per finished run, renamed into place when complete
        <table>.parquet        the study's tables (measurements, perturbations, ...)
        status.json            {"run", "status": "ok" | "error", "error", "seconds", "tables"}
      work/truth_cache/<key>/  cached truth renders (renderlab.campaign.cache)

A run is staged in ``runs/.NNNNNN.staging-*`` and renamed to ``runs/NNNNNN`` only when all of its files
are written, so a killed campaign never leaves a half-written run; ``--resume`` skips runs whose folder
says ``ok`` and re-executes the rest (errors included). Runs are indexed, so none can be doubled.
"""

from __future__ import annotations

import contextlib
import json
import os
import secrets
import shutil
from pathlib import Path

from renderlab import plugins
from renderlab.campaign.compact import read_raw_tables
from renderlab.contracts.file_models import (
    RUNS_FORMAT,
    CampaignManifest,
    RunStatus,
    RunStatuses,
    RunStatusFile,
    plan_digest,
)
from renderlab.contracts.schemas import check_campaign_table, expected_kind, read_parquet
from renderlab.errors import UserError
from renderlab.inputs import read_checked, read_json, shown, validate

FORMAT = "renderlab.campaign/1"
MANIFEST = "campaign.json"


def run_dir(campaign_dir: Path, index: int) -> Path:
    return Path(campaign_dir) / "runs" / f"{index:06d}"


def _versions() -> dict:
    import platform
    from importlib import metadata

    out = {"python": platform.python_version()}
    for dist in ("renderlab", "numpy", "scipy", "pyarrow", "mitsuba", "opencv-python-headless", "dask", "distributed"):
        try:
            out[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            pass
    return out


def _write_json_atomic(path: Path, data: dict) -> None:
    tmp = path.with_name(f".{path.name}.{os.getpid()}-{secrets.token_hex(4)}")
    tmp.write_text(json.dumps(data, indent=1, allow_nan=False) + "\n", encoding="utf-8")
    os.replace(tmp, path)


def read_manifest(campaign_dir: Path) -> dict:
    """``campaign.json``, validated (:class:`renderlab.contracts.file_models.CampaignManifest`)."""
    p = Path(campaign_dir) / MANIFEST
    if not os.path.lexists(p):
        raise UserError(f"{shown(campaign_dir)} is not a campaign folder (no {MANIFEST})")
    return read_checked(p, CampaignManifest, "campaign manifest")  # a FIFO or device is refused by name


def _table_names(st: dict, where: Path) -> list[str]:
    """The run's table names: plain identifiers inside the run folder, never paths (checked by the status model)."""
    return list(st.get("tables", []))


def _first_difference(a, b, where="") -> str:
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            if a.get(k) != b.get(k):
                return _first_difference(a.get(k), b.get(k), f"{where}.{k}" if where else k)
    return where or "(root)"


def open_campaign(campaign_dir: Path, plan, *, resume: bool) -> dict:
    """Create the folder and manifest, or (``resume``) check that the existing plan is the same one."""
    d = Path(campaign_dir)
    if d.exists() and not d.is_dir():
        raise UserError(f"--out {d} exists and is not a directory")
    plan_dict = plan.plan_dict()
    if (d / MANIFEST).is_file():
        if not resume:
            raise UserError(f"--out {d} already holds a campaign; pass --resume to continue it or choose a new --out")
        old = read_manifest(d)
        if old.get("plan") != plan_dict:
            key = _first_difference(old.get("plan") or {}, plan_dict)
            raise UserError(f"--resume: {d} was made with a different plan ({key} differs); use a new --out")
        return old
    if d.is_dir() and any(d.iterdir()):
        raise UserError(f"--out {d} exists, is not empty and holds no campaign")
    try:
        (d / "runs").mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(f"cannot create campaign folder {d}: {exc.strerror or exc}") from None
    base = os.path.relpath(plan.base_dir, d.resolve())
    manifest = {"format": FORMAT, "name": plan.name, "plan": plan_dict, "plan_digest": plan.digest(),
                "scenario_dir": Path(base).as_posix(), "versions": _versions()}
    _write_json_atomic(d / MANIFEST, manifest)
    return manifest


def run_status(campaign_dir: Path, index: int, *, strict: bool = True) -> dict | None:
    """A run's ``status.json``, validated (:class:`renderlab.contracts.file_models.RunStatus`), or None when the run
    has none. An invalid one is a UserError (``strict``) or None (a run to redo on ``--resume``)."""
    p = run_dir(campaign_dir, index) / "status.json"
    if not os.path.lexists(p):
        return None
    try:
        st = read_checked(p, RunStatus, "run status")
        if st["run"] != index:
            raise UserError(f"run status {shown(p)}: 'run' is {st['run']}, but the folder is run {index}")
    except UserError:
        if strict:
            raise
        return None
    return st


def is_finished(campaign_dir: Path, index: int) -> bool:
    st = run_status(campaign_dir, index, strict=False)
    return bool(st) and st.get("status") == "ok"


def write_run(campaign_dir: Path, index: int, tables: dict, status: dict) -> None:
    """Write one run's tables and status atomically (stage, then rename into ``runs/NNNNNN``)."""
    import pyarrow.parquet as pq

    runs = Path(campaign_dir) / "runs"
    final = run_dir(campaign_dir, index)
    stage = runs / f".{final.name}.staging-{os.getpid()}-{secrets.token_hex(4)}"
    stage.mkdir(parents=True)
    try:
        for name, table in sorted(tables.items()):
            pq.write_table(table, str(stage / f"{name}.parquet"))
        (stage / "status.json").write_text(json.dumps({**status, "tables": sorted(tables)}, indent=1) + "\n",
                                           encoding="utf-8")
        if final.exists():
            if is_finished(campaign_dir, index):  # another worker finished this run: keep its files
                shutil.rmtree(stage, ignore_errors=True)
                return
            old = runs / f".{final.name}.old-{os.getpid()}-{secrets.token_hex(4)}"
            os.rename(final, old)
            shutil.rmtree(old, ignore_errors=True)
        os.rename(stage, final)
    except OSError:
        shutil.rmtree(stage, ignore_errors=True)
        if not is_finished(campaign_dir, index):
            raise


def finished_runs(campaign_dir: Path, runs: int) -> list[int]:
    return [i for i in range(runs) if is_finished(campaign_dir, i)]


def load_tables(campaign_dir: Path) -> dict:
    """All finished runs' tables, concatenated per name in run order: ``{name: pyarrow.Table}``."""
    m = read_manifest(campaign_dir)
    own = own_tables(m)
    if is_published(campaign_dir):
        return load_published_tables(campaign_dir, own)
    parts: dict[str, list] = {}
    for i in range(int(m["plan"]["runs"])):
        st = run_status(campaign_dir, i)
        if not st or st.get("status") != "ok":
            continue
        d = run_dir(campaign_dir, i)
        for name in _table_names(st, d / "status.json"):
            parts.setdefault(name, []).append(read_run_table(d / f"{name}.parquet", name, own))
    return {name: concat_parts(name, ts) for name, ts in parts.items()}


def own_tables(manifest: dict) -> tuple[str, ...]:
    """The tables the campaign's study reports itself (``Study.own_tables``; its own schema, read by its own code),
    or none when the study is not registered here."""
    study = manifest["plan"]["study"]
    return tuple(getattr(plugins.studies.get(study), "own_tables", ()) or ()) if study in plugins.studies else ()


def read_run_table(path: Path, name: str, own: tuple = (), *, reduced: bool = False):
    """One campaign table file, read with its boundaries and (unless the study reports it itself: ``own``) the
    schema of its kind checked (:func:`renderlab.contracts.schemas.read_parquet`,
    :func:`~renderlab.contracts.schemas.check_campaign_table`)."""
    where = f"table {shown(path)}"
    table = read_parquet(path, where)
    if name in own:
        return table
    try:
        check_campaign_table(name, table, where, reduced=reduced)
    except ValueError as exc:
        raise UserError(str(exc)) from None
    return table


def concat_parts(name: str, parts: list):
    """The runs' tables of one name, concatenated (UserError when their columns cannot be joined)."""
    import pyarrow as pa

    try:
        return pa.concat_tables(parts, promote_options="permissive")
    except (pa.ArrowException, ValueError, TypeError) as exc:
        raise UserError(f"the runs' {name} tables do not fit together: {' '.join(str(exc).split())[:160]}") from None


def run_statuses(campaign_dir: Path) -> list[dict]:
    """Status of every planned run (``{"run": i, "status": "missing"}`` where none was written)."""
    m = read_manifest(campaign_dir)
    if is_published(campaign_dir):
        out = published_statuses(campaign_dir)
        beyond = [s["run"] for s in out if s["run"] >= m["plan"]["runs"]]
        if beyond:
            raise UserError(f"{shown(campaign_dir)}: runs.json lists run {beyond[0]}, but the plan has "
                            f"{m['plan']['runs']} runs")
        return out
    return [run_status(campaign_dir, i) or {"run": i, "status": "missing"} for i in range(int(m["plan"]["runs"]))]


# the published layout (renderlab.campaign.publish writes it), read like a live campaign folder
TABLES = "tables"
STATUSES = "runs.json"


def is_published(folder: Path) -> bool:
    """A published study folder (``tables/`` and ``runs.json`` beside ``campaign.json``, no ``runs/``)."""
    d = Path(folder)
    return (d / TABLES).is_dir() and os.path.lexists(d / STATUSES) and not (d / "runs").is_dir()


def load_published_tables(folder: Path, own: tuple = ()) -> dict:
    """``{name: pyarrow.Table}`` of a published folder (names are plain identifiers inside ``tables/``; each table
    checked as :func:`read_run_table` checks a run's)."""
    reduced = read_raw_tables(Path(folder) / TABLES)  # tables the study publishes reduced: core columns not required
    out = {}
    for p in sorted((Path(folder) / TABLES).glob("*.parquet")):
        if not p.stem.isidentifier() or p.is_symlink():
            raise UserError(f"{shown(p)}: published table names must be plain identifiers (no links)")
        out[p.stem] = read_run_table(p, p.stem, own, reduced=p.stem in reduced)
    return out


def write_statuses(folder: Path, manifest: dict, statuses: list[dict]) -> None:
    """Write ``runs.json`` (:class:`~renderlab.contracts.file_models.RunStatusFile`): ``statuses`` under the digest
    of ``manifest``'s plan."""
    doc = {"format": RUNS_FORMAT, "plan_digest": plan_digest(manifest["plan"]), "runs": statuses}
    (Path(folder) / STATUSES).write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")


def published_statuses(folder: Path) -> list[dict]:
    """The runs of ``runs.json``, validated (each run once): a :class:`~renderlab.contracts.file_models.RunStatusFile`
    whose plan digest is that of ``campaign.json``'s plan, or the bare list older folders hold (``RunStatuses``)."""
    p = Path(folder) / STATUSES
    data = read_json(p, "run statuses")
    if isinstance(data, dict):
        validate(RunStatusFile, data, f"run statuses {shown(p)}")
        own = plan_digest(read_manifest(folder)["plan"])
        if data["plan_digest"] != own:
            raise UserError(f"run statuses {shown(p)}: written for another campaign (plan digest "
                            f"{data['plan_digest']}, campaign.json's plan {own})")
        data = data["runs"]
    else:
        validate(RunStatuses, data, f"run statuses {shown(p)}")
    runs = [s["run"] for s in data]
    if len(set(runs)) != len(runs):
        raise UserError(f"run statuses {shown(p)}: a run is listed twice")
    return data


def finished_campaign(campaign_dir: Path, purpose: str) -> tuple[dict, dict, list[dict]]:
    """(manifest, tables, run statuses) of a campaign or published study folder that has finished runs;
    UserError (``no finished runs to <purpose>``) otherwise."""
    manifest = read_manifest(campaign_dir)
    tables = load_tables(campaign_dir)
    if not tables:
        raise UserError(f"campaign {shown(campaign_dir)} has no finished runs to {purpose}")
    own = own_tables(manifest)
    empty = [n for n, t in sorted(tables.items())
             if t.num_rows == 0 and n not in own and expected_kind(n, t) != "other"]
    if empty:
        raise UserError(f"campaign {shown(campaign_dir)}: the {empty[0]} table has no rows in any run; nothing to "
                        f"{purpose}")
    return manifest, tables, run_statuses(campaign_dir)


@contextlib.contextmanager
def staged_folder(out_dir: Path, what: str):
    """Yield a hidden sibling staging folder of ``out_dir``; when the block ends normally every entry moves into
    ``out_dir`` (an entry of the same name is replaced; other files of ``out_dir`` are kept). The stage is always
    removed, and an ``OSError`` becomes one UserError line naming ``what``."""
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise UserError(f"--out {out_dir} exists and is not a directory")
    stage = out_dir.parent / f".{out_dir.name}.staging-{os.getpid()}-{secrets.token_hex(4)}"
    try:
        stage.mkdir(parents=True)
        yield stage
        out_dir.mkdir(parents=True, exist_ok=True)
        for f in sorted(stage.iterdir()):
            target = out_dir / f.name
            if target.is_dir() and not target.is_symlink():
                shutil.rmtree(target)
            os.replace(f, target)
    except OSError as exc:
        raise UserError(f"cannot write {what} into {out_dir}: {exc.strerror or exc}") from None
    finally:
        shutil.rmtree(stage, ignore_errors=True)
