"""docs/extending.md "Add an observable kind" runs as written: its module block saved as ``mykind.py``, its
entry-point block naming that module's objects, its use block run in a fresh interpreter beside it, with the output
the page states."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import tomllib
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def _section() -> str:
    text = (REPO / "docs" / "extending.md").read_text(encoding="utf-8")
    start = text.index("## Add an observable kind")
    end = text.index("\n## ", start + 3)
    return text[start:end]


def _blocks(lang: str) -> list[str]:
    return re.findall(rf"```{lang}\n(.*?)```", _section(), re.S)


def test_add_an_observable_kind_runs_as_written(tmp_path):
    module, use = _blocks("python")
    assert module.startswith("# mykind.py\n")
    (tmp_path / "mykind.py").write_text(module, encoding="utf-8")
    entry = tomllib.loads(_blocks("toml")[0])["project"]["entry-points"]
    targets = [t for group in entry.values() for t in group.values()]
    assert set(entry) == {"renderlab.observables", "renderlab.hot_pixel_methods"}
    for target in targets:  # every entry point names an object of the module
        mod, attr = target.split(":")
        assert mod == "mykind" and re.search(rf"^(class {attr}\b|{attr} = )", module, re.M), target
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), os.environ.get("PYTHONPATH", "")])}
    res = subprocess.run([sys.executable, "-c", use], cwd=tmp_path, env=env, capture_output=True, text=True,
                         timeout=300)
    assert res.returncode == 0, res.stderr[-3000:]
    stated = [ln[2:] for ln in use.splitlines() if ln.startswith("# ")]
    assert res.stdout.splitlines() == stated, res.stdout
