"""Compact the published tables of the Retina-vs-SPC study and its error budget in place (the results policy of
:mod:`renderlab.campaign.compact`): ``retina_vs_spc``, ``retina_vs_spc_truth_perturbed`` and its ``nominal``
companion through the study's ``publish_tables`` (:func:`renderlab.studies.retina_vs_spc.report.publish_tables`),
``error_budget`` through the budget's (:func:`renderlab.studies.retina_vs_spc.budget.plan.publish_tables`); every
full table a reduction changed is recorded in the folder's ``tables/raw_tables.json``.

    .venv/bin/python investigations/results_compaction/compact_retina_vs_spc.py [--root ROOT]

``ROOT`` holds the ``results/`` folder (default: the repository); a copy under /tmp is where to try it first.
"""

from __future__ import annotations

import argparse
from pathlib import Path

CAMPAIGNS = ("retina_vs_spc", "retina_vs_spc_truth_perturbed", "retina_vs_spc_truth_perturbed/nominal")
BUDGET = "error_budget"
BUDGET_COMMAND = "the commands of results/error_budget/README.md (budget run, probe, crlb, navigation-budget)"


def main(argv: list[str] | None = None) -> int:
    from renderlab.campaign.compact import compact_folder, study_transform
    from renderlab.studies.retina_vs_spc.budget.plan import publish_tables

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--root", type=Path, default=Path(__file__).resolve().parents[2],
                    help="folder holding results/ (default: the repository)")
    args = ap.parse_args(argv)
    results = args.root / "results"
    done = [(f, compact_folder(results / f, study_transform(results / f))) for f in CAMPAIGNS]
    done.append((BUDGET, compact_folder(results / BUDGET, publish_tables, command=BUDGET_COMMAND)))
    for folder, sizes in done:
        for name, (a, b) in sorted(sizes.items()):
            print(f"results/{folder}/tables/{name}.parquet: {a} -> {b} bytes")
        print(f"results/{folder}: {sum(a for a, _ in sizes.values())} -> {sum(b or 0 for _, b in sizes.values())} bytes")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
