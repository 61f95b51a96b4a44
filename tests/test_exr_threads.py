"""EXR writes on several threads (renderlab.files.openexr_lib): the same bytes as one thread, no OpenEXR pool thread
left after a write, and a forked process that writes afterwards does not hang."""

from __future__ import annotations

import numpy as np
import OpenEXR
import pytest

from renderlab.files.imageio import read_exr, write_exr


def _exr_pool_threads() -> int:
    """OpenEXR's global thread count (Imf::globalThreadCount), read from its own library."""
    import ctypes

    major, minor = str(OpenEXR.OPENEXR_VERSION).split(".")[:2]
    ns = f"Imf_{major}_{minor}"
    fn = getattr(ctypes.CDLL(OpenEXR.__file__), f"_ZN{len(ns)}{ns}17globalThreadCountEv")
    fn.restype = ctypes.c_int
    return fn()


def _write_in_forked_child(path: str) -> None:
    write_exr(path, {"Y": np.ones((64, 32), np.float32)})


@pytest.mark.parametrize("compression", ["zip", "rle"])
def test_exr_threads_give_the_same_bytes_and_leave_no_pool(tmp_path, monkeypatch, compression):
    """Line blocks are compressed on every CPU (openexr_lib.exr_threads): the file is byte for byte the one a single
    thread writes (forced with exr_threads = 1), OpenEXR's pool holds no thread after the write, and a forked
    process writes an EXR afterwards without hanging on a pool whose threads it did not inherit."""
    import multiprocessing

    from renderlab.files import openexr_lib

    rng = np.random.default_rng(4)
    ch = {"Y": rng.normal(size=(200, 96)).astype(np.float32).round(2), "id": rng.integers(0, 4, (200, 96), np.uint32)}
    write_exr(tmp_path / "many.exr", ch, compression=compression)
    assert _exr_pool_threads() == 0
    monkeypatch.setattr(openexr_lib, "exr_threads", lambda: 1)
    write_exr(tmp_path / "one.exr", ch, compression=compression)
    assert (tmp_path / "many.exr").read_bytes() == (tmp_path / "one.exr").read_bytes()
    monkeypatch.undo()
    child = multiprocessing.get_context("fork").Process(target=_write_in_forked_child, args=(str(tmp_path / "c.exr"),))
    child.start()
    child.join(60)
    if child.is_alive():  # a hang: end it, then fail
        child.kill()
        child.join()
    assert child.exitcode == 0, child.exitcode
    assert read_exr(tmp_path / "c.exr")["Y"].shape == (64, 32)
