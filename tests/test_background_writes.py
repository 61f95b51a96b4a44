"""Frame files written in a background thread while the next frame renders (renderlab.files.background).

The same files, byte for byte, as the sequential loop (a real render of the analytic world, both ways, every file
compared); errors of a write raised in the caller's thread with nothing left behind; order, bound and cancel of the
job queue.
"""

import threading
import time
from pathlib import Path

import numpy as np
import pytest

from renderlab.errors import UserError
from renderlab.files.background import BackgroundJobs
from renderlab.files.truthset import TruthSet, TruthSetWriter
from renderlab.pipeline import write_frames
from renderlab.pipeline.frame_api import Renderer

REPO = Path(__file__).resolve().parents[1]
SMALL = ["camera.width=48", "camera.height=32", "camera.fx=60", "camera.fy=60", "camera.cx=23.5", "camera.cy=15.5",
         "render.spp=4", "trajectory.frames=3"]


def _files(root: Path) -> dict:
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def test_background_files_equal_sequential_files_byte_for_byte(tmp_path):
    r = Renderer(REPO / "scenes" / "analytic_sphere_box.toml", overrides=SMALL)
    specs = r.plan.frames
    head = {"scenario": r.scenario.to_dict(), "seed": r.scenario.render.seed, "render_frame": r.plan.render_frame}
    out = {mode: write_frames(tmp_path / str(mode), r, specs, [r.seed_for(s.index) for s in specs], head=head,
                              background=mode) for mode in (False, True)}
    a, b = _files(out[False]), _files(out[True])
    assert len(a) >= 3 * len(specs) + 2  # EXR, DN PNG, preview per frame + manifest + contact sheet
    assert sorted(a) == sorted(b)
    assert [k for k in a if a[k] != b[k]] == []
    ts = TruthSet.open(out[True])
    assert len(ts) == len(specs) and np.array_equal(ts.load(2).dn, r.frame(2).dn)


def _frame(k):
    rng = np.random.default_rng(k)
    ch = {n: rng.normal(0, 10, (8, 12)).astype(np.float32)
          for n in ("Y", "P.X", "P.Y", "P.Z", "N.X", "N.Y", "N.Z", "range")}
    ch["id"] = np.zeros((8, 12), np.int32)
    return ch, rng.integers(0, 4096, (8, 12)).astype(np.uint16)


def test_a_failed_background_write_is_raised_and_leaves_nothing(tmp_path):
    out = tmp_path / "set"
    with pytest.raises(UserError, match="cannot write EXR"):
        with TruthSetWriter(out, {"renderer": {"name": "x"}}, background=True) as w:
            ch, dn = _frame(0)
            w.add_frame(0, 0.0, ch, dn, {}, dn_bits=12)
            w.flush()
            (w.staging_dir / "frames" / "000000.exr").unlink()
            (w.staging_dir / "frames" / "000000.png").unlink()
            (w.staging_dir / "frames").rmdir()  # the next frame's EXR cannot be written: the OpenEXR error
            for k in (1, 2, 3):
                w.add_frame(k, float(k), *_frame(k), {}, dn_bits=12)
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_out_of_range_dn_is_refused_in_the_callers_thread(tmp_path):
    with TruthSetWriter(tmp_path / "set", {}, background=True) as w:
        ch, dn = _frame(0)
        dn[0, 0] = 4096
        with pytest.raises(ValueError, match="dn values must be in 0..4095"):
            w.add_frame(0, 0.0, ch, dn, {}, dn_bits=12)
        w.add_frame(1, 1.0, *_frame(1), {}, dn_bits=12)
    assert [f["index"] for f in TruthSet.open(tmp_path / "set").manifest["frames"]] == [1]


def test_jobs_run_in_order_bounded_and_cancel_drops_the_waiting_ones():
    jobs, done, gate = BackgroundJobs(depth=1), [], threading.Event()
    jobs.submit(lambda: (gate.wait(5), done.append(0)))
    jobs.submit(lambda: done.append(1))  # waits in the queue (depth 1)
    t = threading.Thread(target=jobs.submit, args=(lambda: done.append(2),))
    t.start()
    time.sleep(0.2)
    assert t.is_alive() and done == []  # the queue is full: the third submit blocks
    gate.set()
    t.join(5)
    jobs.flush()
    assert done == [0, 1, 2]
    gate.clear()
    jobs.submit(lambda: (gate.wait(5), done.append(3)))
    jobs.submit(lambda: done.append(4))
    threading.Timer(0.2, gate.set).start()
    jobs.close(cancel=True)
    assert done == [0, 1, 2, 3]  # the running job finished, the waiting one was dropped
    with pytest.raises(RuntimeError, match="closed"):
        jobs.submit(lambda: None)


def test_the_first_error_is_raised_once_and_later_jobs_are_skipped():
    jobs, done = BackgroundJobs(depth=2), []

    def fail():
        raise UserError("disk full")

    jobs.submit(fail)
    jobs.submit(lambda: done.append(1))
    with pytest.raises(UserError, match="disk full"):
        jobs.flush()
    assert done == []
    jobs.flush()  # reported once
    jobs.close()



def test_an_interrupted_set_waits_for_the_writer_and_leaves_nothing(tmp_path):
    out = tmp_path / "set"
    with pytest.raises(KeyboardInterrupt):
        with TruthSetWriter(out, {}, background=True) as w:
            for k in range(3):
                w.add_frame(k, float(k), *_frame(k), {}, dn_bits=12)
            thread = w._jobs._thread
            raise KeyboardInterrupt
    assert not thread.is_alive() and not out.exists() and list(tmp_path.iterdir()) == []
