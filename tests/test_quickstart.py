"""docs/quickstart.md runs as written (its one Python block, from the repository root)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def test_quickstart_runs():
    text = (REPO / "docs" / "quickstart.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    assert len(blocks) == 1 and len(blocks[0].splitlines()) <= 40
    res = subprocess.run([sys.executable, "-c", blocks[0]], cwd=REPO, env={**os.environ, "MPLBACKEND": "Agg"},
                         capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-3000:]
    assert "landmark 0 at (s, l) =" in res.stdout and "retina s bias" in res.stdout, res.stdout
