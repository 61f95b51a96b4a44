"""An EV5 truth set is byte-identical whatever the thread count, site.json included (its floats are rounded to 10
significant digits: the global-shape statistics come from multithreaded reductions whose last digits can depend on
it; at this test's coarse size they agree even unrounded, the rounding guards the full world)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
COARSE = ["--frames", "1", "--set", "world.facet_m=8.0", "--set", "world.site.cell_m=0.1", "--set",
          "world.landmarks.1.spacing_m=0.2", "--set",
          "world.landmarks.2.spacing_m=0.2", "--set", "render.spp=1", "--set", "camera.width=32", "--set",
          "camera.height=32", "--set", "camera.fx=152", "--set", "camera.fy=152", "--set", "camera.cx=15.5",
          "--set", "camera.cy=15.5", "--quiet"]


def test_site_json_same_bytes_with_1_and_2_threads(tmp_path):
    out = {}
    for n in (1, 2):
        env = {**os.environ, "NUMBA_NUM_THREADS": str(n), "OMP_NUM_THREADS": str(n), "OPENBLAS_NUM_THREADS": str(n),
               "RENDERLAB_THREADS": str(n), "MPLBACKEND": "Agg"}
        d = tmp_path / f"t{n}"
        res = subprocess.run([sys.executable, "-m", "renderlab", "render", str(REPO / "scenes" / "ev5_descent.toml"),
                              "--out", str(d), *COARSE], env=env, capture_output=True, text=True, timeout=600)
        assert res.returncode == 0, res.stderr[-2000:]
        out[n] = {f.relative_to(d).as_posix(): f.read_bytes() for f in sorted(d.rglob("*")) if f.is_file()}
    assert "site.json" in out[1] and sorted(out[1]) == sorted(out[2])
    assert [k for k in out[1] if out[1][k] != out[2][k]] == []  # every file of the truth set, site.json included
