"""A campaign plan: scenario + N runs + perturbations, one spawned ``SeedSequence`` per run.

Run ``i`` is seeded by ``SeedSequence(seed, spawn_key=(i,))``, which is exactly the ``i``-th child of
``SeedSequence(seed).spawn(N)``: any run can be replayed alone, and the seeds of runs 0..N-1 do not
depend on N (a campaign can be extended without changing its first runs).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from renderlab import plugins
from renderlab import plugins as registry
from renderlab.campaign.cache import file_hashes
from renderlab.contracts.file_models import MAX_RUNS, plan_digest  # noqa: F401  (the plan's bound, written once)
from renderlab.errors import UserError
from renderlab.inputs import short


@dataclass(frozen=True)
class RunTask:
    """Everything a worker needs to execute one run (picklable: plain data only)."""

    campaign_dir: str
    campaign: str
    study: str
    scenario: dict
    base_dir: str
    index: int
    seed: int
    plugins: tuple = ()  #: (registry, name, "module:attr") the user typed on the command line (``--plugin``)

    def seed_sequence(self) -> np.random.SeedSequence:
        return run_seed_sequence(self.seed, self.index)


def run_seed_sequence(seed: int, index: int) -> np.random.SeedSequence:
    """The run's ``SeedSequence``: the ``index``-th spawned child of ``SeedSequence(seed)``."""
    return np.random.SeedSequence(int(seed), spawn_key=(int(index),))


@dataclass(frozen=True)
class CampaignPlan:
    """A validated plan. ``scenario`` is a :class:`renderlab.scenario.Scenario`."""

    scenario: object
    base_dir: Path
    runs: int
    seed: int
    study: str
    plugins: tuple = ()  #: user-typed plug-in references, re-registered on every worker (not part of the digest)

    @property
    def name(self) -> str:
        return self.scenario.name

    def plan_dict(self) -> dict:
        """The part of the manifest that must match for ``--resume``: study, runs, seed, scenario and the
        content hash of every file the scenario references (``files``, when it references any), so a changed
        albedo map or mesh under the same name is a different plan."""
        scenario = self.scenario.to_dict()
        out = {"study": self.study, "runs": self.runs,
               "seed": {"entropy": self.seed, "run_seed": "SeedSequence(entropy, spawn_key=(run,))"},
               "scenario": scenario}
        files = file_hashes(scenario, self.base_dir)
        if files:
            out["files"] = files
        return out

    def digest(self) -> str:
        return plan_digest(self.plan_dict())

    def tasks(self, campaign_dir: Path, indices=None) -> list[RunTask]:
        sc = self.scenario.to_dict()
        idx = range(self.runs) if indices is None else indices
        return [RunTask(str(campaign_dir), self.name, self.study, sc, str(self.base_dir), int(i), self.seed,
                        tuple(self.plugins)) for i in idx]


def make_plan(scenario, base_dir: Path, runs: int, seed: int | None = None, study: str | None = None,
              plugins: tuple = ()) -> CampaignPlan:
    """Validate a plan: run count, seed and the study (resolved against the registry).

    Raises
    ------
    UserError
        ``--runs`` out of range, negative seed, or an unknown study / one that does not fit the world.
    """
    if isinstance(runs, bool) or not isinstance(runs, int) or not 1 <= runs <= MAX_RUNS:
        raise UserError(f"--runs must be an integer in 1..{MAX_RUNS}, got {short(runs)}")
    seed = scenario.campaign.seed if seed is None else seed
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise UserError(f"campaign seed must be a non-negative integer, got {short(seed)}")
    name = study or study_for(scenario)
    found = registry.studies.get(name, where="campaign.study: ")  # fails early on an unknown study
    kind = scenario.world.kind
    if kind not in found.worlds:
        raise UserError(f"study '{name}' runs on world kind {' or '.join(repr(w) for w in found.worlds)}, "
                        f"not '{kind}'")
    if found.check is not None:
        found.check(scenario)
    return CampaignPlan(scenario=scenario, base_dir=Path(base_dir).resolve(), runs=runs, seed=seed, study=name,
                        plugins=tuple(plugins))


def study_for(scenario) -> str:
    """The study named by ``scenario.campaign.study`` or the default of its world kind."""
    if scenario.campaign.study:
        return scenario.campaign.study
    kind = scenario.world.kind
    if kind not in plugins.DEFAULT_STUDY:
        raise UserError(f"no campaign study for world kind '{kind}' yet; set campaign.study "
                        f"(registered: {', '.join(plugins.studies.names())})")
    return plugins.DEFAULT_STUDY[kind]
