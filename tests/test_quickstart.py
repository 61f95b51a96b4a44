"""docs/quickstart.md runs as written (each Python block, from the repository root)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def _blocks() -> list[str]:
    text = (REPO / "docs" / "quickstart.md").read_text(encoding="utf-8")
    return re.findall(r"```python\n(.*?)```", text, re.S)


def _run(code: str) -> str:
    res = subprocess.run([sys.executable, "-c", code], cwd=REPO, env={**os.environ, "MPLBACKEND": "Agg"},
                         capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-3000:]
    return res.stdout


def test_quickstart_runs():
    blocks = _blocks()
    assert len(blocks) == 2 and all(len(b.splitlines()) <= 40 for b in blocks)
    out = _run(blocks[0])
    assert "landmark 0 at (s, l) =" in out and "retina s bias" in out, out


def test_quickstart_frame_loop_runs():
    """The in-the-loop block: four frames from moved poses, each with DN, AOVs and visible landmarks."""
    out = _run(_blocks()[1])
    lines = [ln for ln in out.splitlines() if ln.startswith("frame ")]
    assert "EV5_FIXED" in out and len(lines) == 4, out
    assert all("landmarks visible" in ln and "nan" not in ln for ln in lines), out
