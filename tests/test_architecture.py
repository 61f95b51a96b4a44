"""The declared architecture holds: import-linter contracts (layers, study independence, self-contained
estimators; function-level imports included), no import cycle (every import statement counted, function-level ones
included), file and function sizes, contracts written once."""

from __future__ import annotations

import ast
import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

#: functions allowed over 80 lines, and why
LONG_FUNCTION_EXCEPTIONS = {
    ("estimators/retina/raster.py", "raster_pinhole"): "one numba kernel; splitting it costs a call per pixel",
    ("renderlab/render/mitsuba_bsdf.py", "_build_classes"): "defines the four Mitsuba BSDF classes for the active "
                                                           "variant (class bodies count as its lines)",
}


def test_import_linter_contracts_are_kept():
    from importlinter.cli import lint_imports

    assert lint_imports(config_filename=str(REPO / "pyproject.toml"), no_cache=True, no_logo=True) == 0


def _sources():
    return sorted(p for pkg in ("renderlab", "estimators") for p in (REPO / pkg).rglob("*.py"))


def import_graph(root: Path, packages=("renderlab", "estimators")) -> tuple[dict, int, int]:
    """(module → the internal modules it imports, module-level import statements, function-level ones) from every
    ``import`` / ``from`` statement of every file under ``root/<package>`` (relative imports resolved; ``from a
    import b`` names module ``a.b`` when that is a module, else ``a``). Only imports of ``packages`` count."""
    files = {}
    for pkg in packages:
        for f in (root / pkg).rglob("*.py"):
            parts = list(f.relative_to(root).with_suffix("").parts)
            files[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = f
    graph, top, inner = {m: set() for m in files}, 0, 0
    for mod, f in files.items():
        tree = ast.parse(f.read_text())
        in_function = {id(n) for fn in ast.walk(tree) if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef))
                       for n in ast.walk(fn)}
        package = mod.split(".") if f.name == "__init__.py" else mod.split(".")[:-1]
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    base = ".".join(package[: len(package) - node.level + 1] + ([node.module] if node.module else []))
                names = [f"{base}.{a.name}" for a in node.names]
            else:
                continue
            hits = set()
            for name in names:
                while name and name not in files:
                    name = name.rpartition(".")[0]
                if name and name != mod and name.split(".")[0] in packages:
                    hits.add(name)
            graph[mod] |= hits
            if hits:
                inner, top = (inner + 1, top) if id(node) in in_function else (inner, top + 1)
    return graph, top, inner


def cycles(graph: dict) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan's algorithm, iterative)."""
    index, low, on, stack, out, counter = {}, {}, set(), [], [], [0]
    for start in graph:
        if start in index:
            continue
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = counter[0]
        counter[0] += 1
        stack.append(start)
        on.add(start)
        while work:
            v, it = work[-1]
            for w in it:
                if w not in index:
                    index[w] = low[w] = counter[0]
                    counter[0] += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                    break
                if w in on:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = []
                    while True:
                        w = stack.pop()
                        on.discard(w)
                        comp.append(w)
                        if w == v:
                            break
                    if len(comp) > 1:
                        out.append(sorted(comp))
    return out


def test_the_cycle_check_finds_a_cycle_through_function_level_and_relative_imports(tmp_path):
    pkg = tmp_path / "renderlab" / "sub"
    pkg.mkdir(parents=True)
    (tmp_path / "renderlab" / "__init__.py").write_text("")
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("def f():\n    from .b import g\n    return g()\n")
    (pkg / "b.py").write_text("from renderlab.sub import c\n")
    (pkg / "c.py").write_text("import os\n\n\ndef h():\n    from renderlab.sub.a import f\n")
    graph, top, inner = import_graph(tmp_path, ("renderlab",))
    assert cycles(graph) == [["renderlab.sub.a", "renderlab.sub.b", "renderlab.sub.c"]]
    assert (top, inner) == (1, 2)
    (pkg / "c.py").write_text("import os\n")
    assert cycles(import_graph(tmp_path, ("renderlab",))[0]) == []


def test_no_import_cycle_counting_every_import():
    assert cycles(import_graph(REPO)[0]) == []


def test_no_file_over_400_lines():
    big = {str(p.relative_to(REPO)): p.read_text().count("\n") for p in _sources()}
    assert {k: v for k, v in big.items() if v > 400} == {}


def test_no_function_over_80_lines_except_the_listed():
    long = {}
    for p in _sources():
        rel = str(p.relative_to(REPO))
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1
                if n > 80 and (rel, node.name) not in LONG_FUNCTION_EXCEPTIONS:
                    long[(rel, node.name)] = n
    assert long == {}


def test_measurement_schema_is_written_once():
    """No module but renderlab.contracts spells out the landmark table's core columns."""
    marker = '"err_s", "err_l", "score"'
    hits = [str(p.relative_to(REPO)) for p in _sources() + sorted((REPO / "tests").glob("*.py"))
            if marker in p.read_text() and "contracts" not in p.parts and p.name != "test_architecture.py"]
    assert hits == []


def test_no_reference_to_a_design_file_outside_the_project():
    hits = [str(p.relative_to(REPO)) for p in _sources() + sorted((REPO / "tests").glob("*.py"))
            if "design.md" in p.read_text() and p.name != "test_architecture.py"]
    assert hits == []


def test_truth_cache_fingerprint_covers_files_that_exist():
    """Every truth-side module the cache key hashes exists (a renamed module would silently drop out of the key)."""
    from renderlab.campaign import cache

    root = REPO / "renderlab"
    assert [m for m in cache._TRUTH_MODULES if not (root / m).is_file()] == []
    assert [p for p in cache._TRUTH_PACKAGES if not (root / p).is_dir()] == []


def test_every_estimator_package_cites_its_references():
    """Each package of ``estimators`` has a References section whose entries give a DOI or say there is none."""
    missing = {}
    for init in sorted((REPO / "estimators").glob("*/__init__.py")):
        doc = ast.get_docstring(ast.parse(init.read_text())) or ""
        refs = doc.split("References\n----------\n", 1)[1] if "References\n----------\n" in doc else ""
        entries = [e for e in refs.split("\n\n") if e.strip()]
        bad = [e[:60] for e in entries if "doi:" not in e and "no DOI" not in e and "none is given" not in e]
        if not entries or bad:
            missing[init.parent.name] = bad or "no References section"
    assert missing == {}


def test_no_issue_tracker_numbers_in_code():
    """Code, docstrings and tests name the finding, not a number of a tracker outside the repository."""
    hits = [f"{p.relative_to(REPO)}:{k}" for p in _sources() + sorted((REPO / "tests").glob("*.py"))
            + sorted((REPO / "benchmarks").glob("*.py")) for k, line in enumerate(p.read_text().splitlines(), 1)
            if re.search(r"\bissues? [0-9]+\b", line) and p.name != "test_architecture.py"]
    assert hits == []


def test_at_most_a_quarter_of_internal_imports_are_inside_functions():
    """Lazy imports are for heavy third-party packages (``renderlab --help`` stays instant); imports of the lab's own
    modules sit at module level unless that would load something heavy at ``--help`` or make a cycle."""
    _, top, inner = import_graph(REPO)
    assert inner / (top + inner) <= 0.25, (top, inner)


def test_help_loads_no_heavy_package():
    import subprocess
    import sys

    code = ("import sys, contextlib, io\nfrom renderlab.cli import main\ntry:\n"
            "    with contextlib.redirect_stdout(io.StringIO()):\n        main(['--help'])\nexcept SystemExit:\n    pass\n"
            "print(' '.join(sorted({m.split('.')[0] for m in sys.modules})))")
    loaded = set(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                                cwd=REPO).stdout.split())
    heavy = {"numpy", "scipy", "pydantic", "pyarrow", "matplotlib", "mitsuba", "drjit", "bpy", "dask", "numba",
             "cv2", "astropy", "trimesh", "jinja2"}
    assert "renderlab" in loaded and loaded & heavy == set()


def test_ruff_is_clean():
    """The rule set of ``[tool.ruff]`` in pyproject.toml (pycodestyle, pyflakes, import order, bugbear)."""
    import subprocess
    import sys

    r = subprocess.run([sys.executable, "-m", "ruff", "check", "--no-cache", "renderlab", "estimators", "tests"],
                       cwd=REPO, capture_output=True, text=True)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-1000:]


def test_package_root_holds_at_most_twelve_modules():
    """The root of ``renderlab`` keeps the entry points and the lowest layers; everything else lives in a subpackage."""
    root = sorted(p.name for p in (REPO / "renderlab").glob("*.py"))
    assert len(root) <= 12, root


def test_no_test_file_imports_another_test_file():
    """Shared fixtures and helpers live in helper modules (``*_fixtures.py``, ``oracles.py``, ...), not in test files:
    importing a test file runs its module-level code twice and ties two test files together."""
    hits = []
    for p in sorted((REPO / "tests").glob("test_*.py")):
        for node in ast.walk(ast.parse(p.read_text())):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import) else
                     [node.module] if isinstance(node, ast.ImportFrom) and node.module and not node.level else [])
            hits += [f"{p.name} imports {n}" for n in names if n.split(".")[0].startswith("test_")]
    assert hits == []
