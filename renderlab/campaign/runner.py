"""Run a campaign: plan → executor → result store, resumable, with a progress bar."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from renderlab.errors import UserError


@dataclass(frozen=True)
class CampaignResult:
    """What a campaign call did: ``executed`` runs now, ``skipped`` (already finished), ``failed``."""

    path: Path
    runs: int
    executed: int
    skipped: int
    failed: list[dict]


def run_campaign(plan, out_dir: Path, *, executor=None, resume: bool = False, progress: bool = True) -> CampaignResult:
    """Execute every unfinished run of ``plan`` into ``out_dir``.

    Raises
    ------
    UserError
        Bad output folder, a different plan on ``--resume``, or no run of the campaign finished.
    """
    from tqdm import tqdm

    from renderlab.campaign import store
    from renderlab.campaign.executors import InProcessExecutor, execute_run

    out_dir = Path(out_dir)
    store.open_campaign(out_dir, plan, resume=resume)
    done = set(store.finished_runs(out_dir, plan.runs))
    todo = [i for i in range(plan.runs) if i not in done]
    failed = []
    executor = executor or InProcessExecutor()
    if todo:
        with executor as ex, tqdm(total=plan.runs, initial=len(done), desc=f"campaign ({ex.name})", unit="run",
                                  disable=not progress) as bar:
            for status in ex.map_unordered(execute_run, plan.tasks(out_dir, todo)):
                if status["status"] != "ok":
                    failed.append(status)
                bar.update(1)
    if todo and len(failed) == len(todo) and not done:  # nothing at all finished
        first = min(failed, key=lambda s: s["run"])
        raise UserError(f"all {len(todo)} runs failed; run {first['run']}: {first['error']}")
    return CampaignResult(out_dir, plan.runs, len(todo), len(done), sorted(failed, key=lambda s: s["run"]))


def run_campaign_file(scenario_path, out_dir, runs: int, *, overrides=None, workers: int | None = 0,
                      scheduler: str | None = None, resume: bool = False, seed: int | None = None,
                      progress: bool = True) -> CampaignResult:
    """Load a scenario file and run its campaign (what ``renderlab campaign`` and the demo call)."""
    from renderlab.campaign.executors import make_executor
    from renderlab.campaign.plan import make_plan
    from renderlab.scenario import load_scenario

    scenario, base = load_scenario(scenario_path, overrides or [])
    plan = make_plan(scenario, base, runs, seed=seed)
    return run_campaign(plan, out_dir, executor=make_executor(workers, scheduler), resume=resume, progress=progress)
