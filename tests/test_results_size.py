"""Size caps of the repository and of the published results (the results policy, docs/results_policy.md: the tables
a report reads and only those, compact; manifests, READMEs and PNG figures in git; SVG only on demand, ``renderlab
report --svg``; full tables recorded in ``raw_tables.json``).

The caps are measured on the tracked files (``git ls-files``; the working copy's bytes), so scratch files of a
session do not count.
"""

from __future__ import annotations

import hashlib
import subprocess
from collections import defaultdict
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
MB = 1_000_000
pytestmark = pytest.mark.published

#: the policy's budgets
FILE_BUDGET = 2 * MB          # no tracked file anywhere
RESULTS_BUDGET = 40 * MB      # all of results/
NEW_FOLDER_BUDGET = 3 * MB    # a published folder added from now on (and each report/ folder of any)
#: caps of single files (the largest report figure measured 0.67 MB, the largest report/ folder 1.16 MB)
FIGURE_CAP = 1 * MB           # a report's figure (report/*.png, crosscheck.png), as for a new folder's files
TEXT_CAP = 1 * MB             # a CSV, Markdown, HTML, JSON or TOML file under results/


def _tracked(under: str = "") -> dict[str, int]:
    """Tracked path → bytes in the working copy (files deleted in the working copy left out)."""
    try:
        out = subprocess.run(["git", "ls-files", "-z", "--", under or "."], cwd=REPO, capture_output=True,
                             check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        pytest.skip("not a git checkout")
    sizes = {}
    for name in out.decode().split("\0"):
        p = REPO / name
        if name and p.is_file() and not p.is_symlink():
            sizes[name] = p.stat().st_size
    return sizes


def _report_folders(results: dict[str, int]) -> dict[str, int]:
    """Each ``report/`` folder under results/ → bytes of its files."""
    folders: dict[str, int] = defaultdict(int)
    for name, n in results.items():
        parts = name.split("/")
        if "report" in parts[:-1]:
            folders["/".join(parts[: parts.index("report") + 1])] += n
    return dict(folders)


def test_no_svg_under_results():
    svg = sorted(n for n in _tracked("results") if n.lower().endswith(".svg"))
    assert svg == [], f"{len(svg)} SVG files: figures are PNG; SVG is written on demand (renderlab report --svg)"


def test_figures_and_text_files_are_capped():
    results = _tracked("results")
    figures = {n: s for n, s in results.items() if n.endswith(".png") and ("/report/" in n or n.endswith("/crosscheck.png"))}
    assert len(figures) >= 90, "the report figures are found"
    png = {n: s for n, s in figures.items() if s > FIGURE_CAP}
    text = {n: s for n, s in results.items()
            if n.lower().endswith((".csv", ".md", ".html", ".json", ".toml")) and s > TEXT_CAP}
    assert png == {}, f"PNG over {FIGURE_CAP / MB:g} MB: {png}"
    assert text == {}, f"text files over {TEXT_CAP / MB:g} MB: {text}"


def test_every_report_folder_within_the_new_folder_budget():
    big = {f: n for f, n in _report_folders(_tracked("results")).items() if n > NEW_FOLDER_BUDGET}
    assert big == {}, f"report/ folders over {NEW_FOLDER_BUDGET / MB:g} MB: {big}"


def _duplicates() -> list[list[str]]:
    by_hash: dict[str, list[str]] = defaultdict(list)
    for name in _tracked("results"):
        by_hash[hashlib.sha256((REPO / name).read_bytes()).hexdigest()].append(name)
    return sorted(sorted(v) for v in by_hash.values() if len(v) > 1)


def test_no_byte_identical_duplicates_under_results():
    """Tables and figures are written once (a report's summary rows in one summary.csv, no copy under another
    name; each campaign's runs.json names its plan, so two campaigns' statuses differ)."""
    groups = _duplicates()
    assert groups == [], f"{len(groups)} groups of byte-identical files: {groups}"


def test_no_tracked_file_over_the_budget():
    big = {n: s for n, s in _tracked().items() if s > FILE_BUDGET}
    assert big == {}, f"{len(big)} tracked files over {FILE_BUDGET / MB:g} MB: {sorted(big)}"


def test_results_within_the_budget():
    total = sum(_tracked("results").values())
    assert total <= RESULTS_BUDGET, f"results/ holds {total / MB:.1f} MB > {RESULTS_BUDGET / MB:g} MB"
