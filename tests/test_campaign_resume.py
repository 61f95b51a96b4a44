"""SIGKILL a running ``renderlab campaign`` and resume it (the campaign engine's acceptance: exactly N runs, none
doubled, tables identical to an uninterrupted campaign).

The killed campaign is resumed with ``--resume``: exactly N run folders, each run once, and every
table equal (timing column ``t_ms`` excluded) to an uninterrupted campaign with the same seed.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pyarrow.parquet as pq
from campaign_fixtures import SCENE, TINY, tables_equal

from renderlab.campaign import store
from renderlab.cli import main

N = 10


def _args(out: Path, *extra: str) -> list[str]:
    return ["campaign", str(SCENE), "--runs", str(N), "--out", str(out), "--workers", "0", "--quiet",
            "--seed", "11", *[a for kv in TINY for a in ("--set", kv)], *extra]


def test_sigkill_then_resume_equals_uninterrupted(tmp_path):
    killed = tmp_path / "killed"
    proc = subprocess.Popen([sys.executable, "-m", "renderlab", *_args(killed)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    t0 = time.monotonic()
    try:
        while len(store.finished_runs(killed, N)) < 2 if (killed / "campaign.json").is_file() else True:
            assert proc.poll() is None, "campaign ended before it could be killed"
            assert time.monotonic() - t0 < 120
            time.sleep(0.02)
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
    n_before = len(store.finished_runs(killed, N))
    assert 2 <= n_before < N  # killed mid-campaign
    assert main(_args(killed, "--resume")) == 0
    assert main(_args(tmp_path / "straight")) == 0
    runs = sorted(p.name for p in (killed / "runs").iterdir() if not p.name.startswith("."))
    assert runs == [f"{i:06d}" for i in range(N)]  # exactly N, none doubled
    assert [s["status"] for s in store.run_statuses(killed)] == ["ok"] * N
    a, b = store.load_tables(killed), store.load_tables(tmp_path / "straight")
    assert sorted(a) == sorted(b) == ["measurements", "perturbations"]
    for name in a:
        assert a[name].column("run").to_pylist() == b[name].column("run").to_pylist()
        assert tables_equal(a[name], b[name])
    for i in range(N):  # file by file too
        t1 = pq.read_table(store.run_dir(killed, i) / "measurements.parquet")
        t2 = pq.read_table(store.run_dir(tmp_path / "straight", i) / "measurements.parquet")
        assert tables_equal(t1, t2)
