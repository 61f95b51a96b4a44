"""Signals and full disks: nothing half-written is left, and the command says what happened.

* SIGTERM / SIGHUP to a ``renderlab render`` mid-way: exit 143 / 129, one stderr line, no staging folder and no
  output folder left.
* SIGTERM to a ``renderlab campaign`` on a Dask LocalCluster mid-way: exit 143, one line, no staging folder in
  the campaign; ``--resume`` then finishes it. Ctrl-C (SIGINT to the whole process group, workers included):
  exit 130, one line (no worker tracebacks), no worker left.
* A tmpfs filled mid-campaign (root only: ``mount -t tmpfs``; skipped with the reason otherwise): the campaign
  stops with exit 2 and one line naming the disk; after the file system grows, ``--resume`` completes. The same
  campaign without ``--allow-large`` is refused up front (its disk estimate exceeds the free space).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SCENE = REPO / "scenes" / "analytic_sphere_box.toml"
TINY = ["--set", "camera.width=48", "--set", "camera.height=36", "--set", "camera.fx=50", "--set", "camera.fy=49",
        "--set", "camera.cx=24", "--set", "camera.cy=18", "--set", "render.spp=2"]


def _env(tmp_path: Path) -> dict:
    return {**os.environ, "RENDERLAB_CACHE": str(tmp_path / "cache"), "PYTHONUNBUFFERED": "1"}


def _start(args, tmp_path, **kw) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "renderlab", *args], cwd=tmp_path, env=_env(tmp_path),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kw)


def _wait_for(pred, timeout: float = 120.0) -> None:
    t0 = time.monotonic()
    while not pred():
        if time.monotonic() - t0 > timeout:
            raise AssertionError("timed out waiting for the command to get going")
        time.sleep(0.1)


def _leftovers(root: Path) -> list[str]:
    """Hidden staging / replaced / temporary entries anywhere under ``root``."""
    return [str(p.relative_to(root)) for p in root.rglob(".*") if ".staging-" in p.name or ".old-" in p.name]


def _one_line(stderr: str, text: str) -> None:
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(text), stderr
    assert "Traceback" not in stderr


def test_a_signal_inside_deferred_is_raised_when_the_block_ends_and_no_lock_stays_taken():
    """signals.deferred (around the writer queue's lock): the handler does not raise inside the block, so a lock taken
    and released there is free afterwards; Terminated is raised once, at the block's end."""
    import os
    import threading

    from renderlab.files.signals import Terminated, deferred, handled_signals, raise_pending

    lock, steps = threading.Lock(), []
    with handled_signals():
        with pytest.raises(Terminated) as err:
            with deferred():
                lock.acquire()
                os.kill(os.getpid(), signal.SIGTERM)
                for k in range(10000):  # bytecodes: the Python handler has run by the end
                    steps.append(k)
                lock.release()
                steps.append("released")
            steps.append("after the block")  # not reached: the block's end raised
        raise_pending()  # still inside the handlers: the block's raise consumed the signal, none is raised twice
    assert err.value.signum == signal.SIGTERM and steps[-1] == "released"
    assert lock.acquire(blocking=False)


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP])
def test_signal_during_render_leaves_nothing(tmp_path, sig):
    proc = _start(["render", str(SCENE), "--out", "o", "--quiet", "--set", "trajectory.frames=400", *TINY], tmp_path)
    try:
        _wait_for(lambda: any(p.name.startswith(".o.staging-") and (p / "frames").is_dir()
                              and any((p / "frames").iterdir()) for p in tmp_path.iterdir()))
        proc.send_signal(sig)
        out, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 128 + sig, (proc.returncode, err)
    _one_line(err, f"renderlab: interrupted ({signal.Signals(sig).name})")
    assert not (tmp_path / "o").exists()
    assert _leftovers(tmp_path) == []


def test_sigterm_during_dask_campaign_then_resume(tmp_path):
    args = ["campaign", str(SCENE), "--runs", "6", "--out", "c", "--workers", "2", "--quiet",
            "--set", "trajectory.frames=2", *TINY]
    proc = _start(args, tmp_path)
    try:
        _wait_for(lambda: (tmp_path / "c" / "runs" / "000000").is_dir() or (tmp_path / "c" / "runs" / "000001").is_dir())
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=90)
    finally:
        proc.kill()
    assert proc.returncode == 143, err
    _one_line(err, "renderlab: interrupted (SIGTERM)")
    assert _leftovers(tmp_path / "c") == []
    assert (tmp_path / "c" / "campaign.json").is_file()
    res = subprocess.run([sys.executable, "-m", "renderlab", *args, "--resume"], cwd=tmp_path, env=_env(tmp_path),
                         capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr
    assert "6 of 6 runs finished" in res.stdout
    assert _leftovers(tmp_path / "c") == []


def test_ctrl_c_to_the_process_group_of_a_dask_campaign(tmp_path):
    """SIGINT reaches the driver and its workers (a terminal's Ctrl-C): one line, no worker tracebacks."""
    proc = _start(["campaign", str(SCENE), "--runs", "20", "--out", "c", "--workers", "2", "--quiet",
                   "--set", "trajectory.frames=2", *TINY], tmp_path, start_new_session=True)
    try:
        _wait_for(lambda: (tmp_path / "c" / "work" / "truth_cache").is_dir())
        time.sleep(1.0)
        os.killpg(proc.pid, signal.SIGINT)
        out, err = proc.communicate(timeout=90)
    finally:
        proc.kill()
    assert proc.returncode == 130, err
    _one_line(err, "renderlab: interrupted (SIGINT)")
    assert _leftovers(tmp_path / "c") == []
    time.sleep(2.0)
    with pytest.raises(ProcessLookupError):  # no worker of the group is left
        os.killpg(proc.pid, 0)


@pytest.fixture()
def small_tmpfs(tmp_path):
    """A 1.5 MiB tmpfs at ``tmp_path/disk`` (root only)."""
    if os.geteuid() != 0:
        pytest.skip("filling a disk needs a tmpfs mount, which needs root")
    mnt = tmp_path / "disk"
    mnt.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1536k", "tmpfs", str(mnt)], capture_output=True, text=True)
    if r.returncode != 0:
        pytest.skip(f"mount -t tmpfs failed: {r.stderr.strip()}")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], capture_output=True)


def test_disk_filling_mid_campaign_then_resume(small_tmpfs, tmp_path):
    args = ["campaign", str(SCENE), "--runs", "30", "--workers", "0", "--quiet", "--set", "trajectory.frames=2", *TINY]
    refused = subprocess.run([sys.executable, "-m", "renderlab", *args, "--out", str(small_tmpfs / "c")],
                             cwd=tmp_path, env=_env(tmp_path), capture_output=True, text=True, timeout=120)
    assert refused.returncode == 2 and "free at" in refused.stderr, refused.stderr  # the estimate does not fit
    assert list(small_tmpfs.iterdir()) == []

    run = subprocess.run([sys.executable, "-m", "renderlab", *args, "--out", str(small_tmpfs / "c"), "--allow-large"],
                         cwd=tmp_path, env=_env(tmp_path), capture_output=True, text=True, timeout=600)
    assert run.returncode == 2, (run.stdout, run.stderr)
    _one_line(run.stderr, "renderlab: error: ")
    assert f"the disk at {small_tmpfs} is full" in run.stderr and "--resume" in run.stderr, run.stderr
    assert _leftovers(small_tmpfs) == []
    finished = [p for p in (small_tmpfs / "c" / "runs").iterdir() if (p / "status.json").is_file()]
    assert 0 < len(finished) < 30

    subprocess.run(["mount", "-o", "remount,size=64m", str(small_tmpfs)], check=True)
    again = subprocess.run([sys.executable, "-m", "renderlab", *args, "--out", str(small_tmpfs / "c"), "--resume"],
                           cwd=tmp_path, env=_env(tmp_path), capture_output=True, text=True, timeout=600)
    assert again.returncode == 0, again.stderr
    assert "30 of 30 runs finished" in again.stdout
    assert _leftovers(small_tmpfs) == []


def test_a_signal_during_mitsuba_start_up_is_not_reported_as_an_llvm_problem(monkeypatch):
    """A signal whose raise surfaced inside mi.set_variant as an ordinary error (the handler ran in native code)
    ends the command as a signal: no LLVM advice, no fallback to another variant."""
    import mitsuba as mi

    from renderlab.files import signals
    from renderlab.render import variant

    def boom(name):
        signals._state["pending"] = 15  # what the handler records before its raise is lost in native code
        raise RuntimeError("set_variant(): interrupted")

    monkeypatch.setattr(mi, "set_variant", boom)
    monkeypatch.setattr(variant, "_resolved", {})
    with pytest.raises(signals.Terminated):
        variant.init_mitsuba("llvm_ad_mono")
    assert signals._state["pending"] is None
