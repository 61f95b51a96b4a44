"""Investigations live outside the package and the results: ``results/`` holds no script, and every script under
``investigations/`` runs (``--help`` exits 0 with its usage) from the repository root."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SCRIPTS = sorted((REPO / "investigations").rglob("*.py"))


def test_results_hold_no_script():
    assert [p.relative_to(REPO).as_posix() for p in (REPO / "results").rglob("*.py")] == []


def test_the_investigations_are_there():
    names = {p.relative_to(REPO / "investigations").as_posix() for p in SCRIPTS}
    assert {"descent_navigation_map_states/scale_probe.py", "descent_navigation_map_states/scale_geometry.py"} <= names


@pytest.mark.parametrize("script", SCRIPTS, ids=[p.relative_to(REPO / "investigations").as_posix() for p in SCRIPTS])
def test_each_script_answers_help(script):
    r = subprocess.run([sys.executable, str(script.relative_to(REPO)), "--help"], cwd=REPO, capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("usage: ") and script.name in r.stdout.splitlines()[0]


def test_nothing_in_the_lab_imports_an_investigation():
    names = {p.stem for p in SCRIPTS}
    files = [p for pkg in ("renderlab", "estimators", "tests") for p in (REPO / pkg).rglob("*.py")]
    hits = [p.relative_to(REPO).as_posix() for p in files
            if any(f"import {n}" in p.read_text() or f".{n} import" in p.read_text() for n in names)]
    assert hits == []
