"""Every example command of the README runs (at tiny image sizes and run counts) and exits 0.

The commands are read from the README's fenced blocks: lines that start with ``.venv/bin/renderlab``, with ``\\``
continuations joined and ``&&`` chains split. Each runs as a subprocess through ``sys.executable -m renderlab`` in
a temporary folder (``out/`` relative to it). To keep the suite fast, commands that render get overrides that
shrink the camera to at most 64 px wide at the same field of view and 1 sample per pixel, and campaigns run 2 runs.
The set-up-and-demo command is covered by CI (``.ci/run`` runs ``setup.sh``) and ``tests/test_campaign_demo.py``.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def readme_commands() -> list[str]:
    text = (REPO / "README.md").read_text(encoding="utf-8")
    cmds = []
    for block in re.findall(r"```(?:\w*)\n(.*?)```", text, re.S):
        joined = re.sub(r"\\\n\s*", " ", block)
        for line in joined.splitlines():
            line = line.split("   #")[0].strip()
            if line.startswith(".venv/bin/renderlab ") and "SCENARIO" not in line and "TRUTHSET" not in line:
                cmds += [c.strip() for c in line.split("&&")]
    return cmds


def _tiny(argv: list[str]) -> list[str]:
    """Overrides that shrink a rendering command (same field of view, 1 spp) and a campaign's run count."""
    from renderlab.scenario import load_scenario

    cmd = argv[0]
    if cmd not in ("render", "campaign", "crosscheck"):
        return argv
    sets = [argv[i + 1] for i, a in enumerate(argv) if a == "--set"]
    sc, _ = load_scenario(REPO / argv[1], sets)
    cam = sc.camera
    f = min(1.0, 64.0 / cam.width)
    extra = [f"camera.width={max(8, round(cam.width * f))}", f"camera.height={max(8, round(cam.height * f))}",
             f"camera.fx={cam.fx * f}", f"camera.fy={cam.fy * f}", f"camera.cx={(cam.cx + 0.5) * f - 0.5}",
             f"camera.cy={(cam.cy + 0.5) * f - 0.5}", "render.spp=1"]
    out = list(argv)
    if cmd == "campaign" and "--runs" in out:
        out[out.index("--runs") + 1] = "2"
    return out + [a for kv in extra for a in ("--set", kv)]


def test_readme_has_the_examples():
    cmds = readme_commands()
    assert len(cmds) >= 8, cmds
    assert any(c.split()[1] == "publish" for c in cmds) and any("ncc_baseline" in c for c in cmds)


@pytest.mark.parametrize("index", range(len(readme_commands())))
def test_readme_example_runs(index, tmp_path_factory):
    work = tmp_path_factory.getbasetemp() / "readme_out"  # shared: later examples read earlier outputs
    work.mkdir(exist_ok=True)
    cmd = readme_commands()[index]
    argv = _tiny(shlex.split(cmd)[1:])
    argv = [a if not a.startswith("scenes/") else str(REPO / a) for a in argv]
    env = {**os.environ, "MPLBACKEND": "Agg"}
    res = subprocess.run([sys.executable, "-m", "renderlab", *argv], cwd=work, env=env, capture_output=True,
                         text=True, timeout=900)
    assert res.returncode == 0, f"{cmd}\n{res.stderr[-2000:]}"
