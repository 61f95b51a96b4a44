"""Run a campaign: plan → executor → result store, resumable, with a progress bar.

Leftovers of earlier crashes (``runs/.NNNNNN.staging-*``, ``work/truth_cache/.KEY.staging-*``, temporary
manifest files) whose process is gone are removed before the runs start, and this process's own after the
executor has closed (an interrupted campaign leaves nothing half-written). A run that fails because of the
machine (a full or read-only disk, see :func:`renderlab.campaign.executors.environment_errno`) stops the
campaign: no further runs are started and the command fails naming the disk, so ``--resume`` can continue
once there is space. A refused campaign (its executor cannot start, every run failed) that this call
created is removed again: a refusal leaves nothing behind.
"""

from __future__ import annotations

import functools
import os
from dataclasses import dataclass
from pathlib import Path

from renderlab.campaign import store
from renderlab.campaign.executors import InProcessExecutor, execute_run, make_executor
from renderlab.campaign.plan import make_plan
from renderlab.errors import UserError
from renderlab.files.signals import raise_pending, sweep_campaign
from renderlab.scenario import load_scenario


@dataclass(frozen=True)
class CampaignResult:
    """What a campaign call did: ``executed`` runs now, ``skipped`` (already finished), ``failed``."""

    path: Path
    runs: int
    executed: int
    skipped: int
    failed: list[dict]


def mount_point(path: Path) -> Path:
    """The mount point of the file system holding ``path`` (its nearest existing ancestor)."""
    p = Path(os.path.abspath(path))
    while not p.exists() and p != p.parent:
        p = p.parent
    while not os.path.ismount(p) and p != p.parent:
        p = p.parent
    return p


_ENV_WORDS = {"ENOSPC": "is full", "EDQUOT": "is over its quota", "EROFS": "is read-only",
              "EIO": "failed (input/output error)", "ENOMEM": "(memory) ran out"}


def _environment_failure(out_dir: Path, status: dict, finished: int, runs: int) -> UserError:
    code = status.get("env_errno", "")
    where = f"the disk at {mount_point(out_dir)}" if code != "ENOMEM" else "the machine's memory"
    return UserError(f"campaign {out_dir}: stopped after {finished} of {runs} runs: {where} "
                     f"{_ENV_WORDS.get(code, 'failed')} ({code}; run {status['run']}: {status['error']}); "
                     "free it and continue with --resume")


def run_campaign(plan, out_dir: Path, *, executor=None, resume: bool = False, progress: bool = True,
                 timings: str = "inline") -> CampaignResult:
    """Execute every unfinished run of ``plan`` into ``out_dir``.

    ``timings="separate"`` keeps wall-clock timing columns out of the result tables (NaN there, the values in
    each run's ``timings.parquet``), so the same seed gives byte-identical result tables.

    Raises
    ------
    UserError
        Bad output folder, a different plan on ``--resume``, no run of the campaign finished, or a run failed
        because of the machine (full or read-only disk).
    """
    from tqdm import tqdm


    if timings not in ("inline", "separate"):
        raise UserError(f"--timings must be 'inline' or 'separate', got {timings!r}")
    out_dir = Path(out_dir)
    created = None if (out_dir / store.MANIFEST).exists() else out_dir.exists()  # None: an existing campaign
    store.open_campaign(out_dir, plan, resume=resume)
    sweep_campaign(out_dir)
    done = set(store.finished_runs(out_dir, plan.runs))
    todo = [i for i in range(plan.runs) if i not in done]
    failed, env_failure, finished_now = [], None, 0
    fn = execute_run if timings == "inline" else functools.partial(execute_run, timings=timings)
    try:
        if todo:
            with executor or InProcessExecutor() as ex, tqdm(total=plan.runs, initial=len(done), unit="run",
                                                               desc=f"campaign ({ex.name})", disable=not progress) as bar:
                for status in ex.map_unordered(fn, plan.tasks(out_dir, todo)):
                    raise_pending()  # a signal whose raise the garbage collector swallowed stops the campaign here
                    bar.update(1)
                    if status["status"] == "ok":
                        finished_now += 1
                        continue
                    failed.append(status)
                    if status.get("env_errno"):
                        env_failure = status
                        break
        if env_failure is not None:
            raise _environment_failure(out_dir, env_failure, len(done) + finished_now, plan.runs)
        if todo and len(failed) == len(todo) and not done:  # nothing at all finished
            first = min(failed, key=lambda s: s["run"])
            raise UserError(f"all {len(todo)} runs failed; run {first['run']}: {first['error']}")
    except UserError:
        if created is not None and not done and not finished_now:  # refused: leave nothing of a new campaign
            _remove_new_campaign(out_dir, keep_folder=created)
        raise
    finally:
        sweep_campaign(out_dir, own=True)
    return CampaignResult(out_dir, plan.runs, len(todo), len(done), sorted(failed, key=lambda s: s["run"]))


def _remove_new_campaign(out_dir: Path, keep_folder: bool) -> None:
    """Remove what this call created: the whole folder, or (it existed, empty) its contents."""
    import shutil

    if not keep_folder:
        shutil.rmtree(out_dir, ignore_errors=True)
        return
    for p in out_dir.iterdir():
        if p.is_dir() and not p.is_symlink():
            shutil.rmtree(p, ignore_errors=True)
        else:
            p.unlink(missing_ok=True)


def run_campaign_file(scenario_path, out_dir, runs: int, *, overrides=None, workers: int | None = 0,
                      scheduler: str | None = None, resume: bool = False, seed: int | None = None,
                      progress: bool = True) -> CampaignResult:
    """Load a scenario file and run its campaign (what ``renderlab campaign`` and the demo call)."""
    scenario, base = load_scenario(scenario_path, overrides or [])
    plan = make_plan(scenario, base, runs, seed=seed)
    return run_campaign(plan, out_dir, executor=make_executor(workers, scheduler), resume=resume, progress=progress)
