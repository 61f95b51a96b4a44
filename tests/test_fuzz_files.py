"""Fuzz by category: every file the lab reads is validated at its boundary, and small inputs cannot hang or exhaust
the machine.

The families are generated (tests/fuzz_families.py, tests/fuzz_families2.py) over real files made by the lab's own
writers (tests/fuzz_files.py): the metadata models' every declared key, every column of the campaign tables, every
numeric key of every shipped scene, every file slot with every kind of special file, alias bombs and image headers of
several sizes, every malformed ``module:attr`` and every control character of a KVN value. Each family runs in one
``python`` child under a 4 GiB address-space cap (``RLIMIT_AS``), each case in-process there through
:func:`renderlab.cli.main` with a 30 s alarm; a case passes when it exits 2 with exactly one ``renderlab: error:``
line naming its needle, no traceback, nothing created in its working folder, its inputs untouched, and no recorded
callable called, and its longest error line is at most ``MAX_LINE`` characters (values are quoted by a short prefix).
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import pytest

TESTS = Path(__file__).resolve().parent
sys.path.insert(0, str(TESTS))
from fuzz_files import PREFIX, _tree, build_lab, families  # noqa: E402

FAMILIES = list(families())
#: the fewest cases each family must generate (it grows with the models, scenes and slots)
MIN_CASES = {"metadata": 150, "tables": 90, "values": 250, "resources": 100, "references": 60, "outputs": 50}
#: the longest error line any case may print (values are quoted by a short prefix; paths are the test's own)
MAX_LINE = 400
_RESULTS: dict = {}


def _limit_memory():  # pragma: no cover - runs in the child
    resource.setrlimit(resource.RLIMIT_AS, (4 << 30, 4 << 30))


@pytest.fixture(scope="module")
def lab(tmp_path_factory):
    root = tmp_path_factory.mktemp("fuzz_lab")
    env = {"RENDERLAB_CACHE": os.environ.get("RENDERLAB_CACHE")}
    os.environ["RENDERLAB_CACHE"] = str(root.parent / "fuzz_lab_cache")
    try:
        build_lab(root / "lab")
    finally:
        if env["RENDERLAB_CACHE"] is None:
            os.environ.pop("RENDERLAB_CACHE", None)
        else:
            os.environ["RENDERLAB_CACHE"] = env["RENDERLAB_CACHE"]
    before = _tree(root / "lab")
    yield root / "lab"
    assert _tree(root / "lab") == before, "a case changed the shared lab"


def _start(family: str, lab: Path, root: Path) -> subprocess.Popen:
    root.mkdir(parents=True)
    code = (f"import sys; sys.path.insert(0, {str(TESTS)!r}); import fuzz_files; "
            f"fuzz_files.run_family({family!r}, __import__('pathlib').Path({str(lab)!r}), "
            f"__import__('pathlib').Path({str(root)!r}))")
    with open(root / "stderr.txt", "w") as err:  # a file, not a pipe: a chatty child never blocks on it
        return subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.DEVNULL, stderr=err, cwd=root,
                                preexec_fn=_limit_memory, env={**os.environ, "RENDERLAB_CACHE": str(root / "cache")})


def _collect(family: str, root: Path, proc: subprocess.Popen, seconds: float) -> tuple[int, list[dict], float]:
    lines = (root / "results.jsonl").read_text().splitlines() if (root / "results.jsonl").exists() else []
    err = (root / "stderr.txt").read_text(errors="replace")
    assert lines, f"the {family} child wrote nothing: rc {proc.returncode}, {err[-2000:]}"
    n = json.loads(lines[0])["cases"]
    results = [json.loads(x) for x in lines[1:]]
    if len(results) < n:  # the child died inside a case: that case fails
        results.append({"id": f"case {len(results)} (the child died: rc {proc.returncode}, {err.strip()[-300:]!r})",
                        "rc": "died", "lines": 0, "line": "", "longest": 0, "needle": "", "seconds": 0, "created": [],
                        "changed": [], "called": [], "traceback": False})
    return n, results, seconds


def family_results(family: str, lab: Path, tmp: Path) -> tuple[int, list[dict], float]:
    """(cases generated, per-case results, seconds) of one family, each family run in its own capped child, as many
    at once as there are cores (all families started on the first call; cached per session). Under pytest-xdist a
    worker runs only the families of its own tests: the other workers run theirs (every family still runs once)."""
    if family not in _RESULTS:
        pending = [family] if os.environ.get("PYTEST_XDIST_WORKER") else [f for f in FAMILIES if f not in _RESULTS]
        running = {}
        slots = max(1, min(len(pending), len(os.sched_getaffinity(0))))
        while pending or running:
            while pending and len(running) < slots:
                f = pending.pop(0)
                running[f] = (_start(f, lab, tmp / f), time.perf_counter())
            for f, (proc, t0) in list(running.items()):
                if proc.poll() is not None:
                    _RESULTS[f] = _collect(f, tmp / f, proc, time.perf_counter() - t0)
                    del running[f]
                elif time.perf_counter() - t0 > 900:
                    proc.kill()
            time.sleep(0.1)
    return _RESULTS[family]


def problems_of(r: dict) -> list[str]:
    out = []
    if r["rc"] != 2:
        out.append(f"exit {r['rc']}")
    if r["lines"] != 1 or not r["line"].startswith(PREFIX):
        out.append(f"{r['lines']} stderr lines: {r['line'][:200]!r}")
    if r["needle"] and r["needle"] not in r["line"]:
        out.append(f"does not name {r['needle'][:40]!r}: {r['line'][:300]!r}")
    if r["traceback"]:
        out.append("traceback")
    if r["created"] or r["changed"]:
        out.append(f"created {r['created'][:3]} / changed {r['changed'][:3]}")
    if r["called"]:
        out.append(f"called {r['called']}")
    if r["seconds"] > 30:
        out.append(f"took {r['seconds']:.0f} s")
    if r["longest"] > MAX_LINE:  # no error line quotes user data unbounded
        out.append(f"an error line of {r['longest']} characters (> {MAX_LINE}): {r['line'][:120]!r}")
    return out


@pytest.mark.parametrize("family", FAMILIES)
def test_family_refused_cleanly(family, lab, tmp_path_factory, capsys):
    n, results, seconds = family_results(family, lab, tmp_path_factory.getbasetemp() / "fuzz_runs")
    bad = {r["id"]: problems_of(r) for r in results if problems_of(r)}
    clean = len(results) - len(bad)
    with capsys.disabled():
        print(f"\n[fuzz family {family}] {n} cases, {clean} refused cleanly, {seconds:.1f} s")
    assert n >= MIN_CASES[family], f"{family}: only {n} cases generated"
    assert not bad, f"{family}: {len(bad)} of {n} not refused cleanly: " + "; ".join(
        f"{k}: {', '.join(v)}" for k, v in list(bad.items())[:12])
