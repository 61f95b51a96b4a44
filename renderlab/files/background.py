"""File writes in one background thread, in order, so that frame k's files are written while frame k+1 renders.

A truth set's per-frame files (EXR, DN PNG, preview PNG) are written by the same functions, with the same
arguments, as in the loop itself: only *when* changes, so the bytes are the same
(``tests/test_background_writes.py`` compares them). The queue is bounded (``depth`` jobs waiting; the caller
blocks when it is full), so at most ``depth + 1`` frames' arrays are held. The first error of a job is kept, the
jobs after it are skipped, and it is raised in the caller's thread by the next :meth:`BackgroundJobs.submit`,
:meth:`~BackgroundJobs.flush` or :meth:`~BackgroundJobs.close` (the same exception object: a
:class:`renderlab.errors.UserError` stays a one-line error). :meth:`~BackgroundJobs.close` with ``cancel=True``
drops the jobs not yet started and waits for the running one, so a failed truth set's staging folder can be
removed with nothing still writing into it.

What it gains depends on idle cores. On the 2-core machine, where Dr.Jit's kernels keep both cores busy, it gains
nothing measurable (a 1 MP EV5 truth set: 3.28 vs 3.39 s and 3.95 vs 3.76 s per two frames in two quiet runs,
``benchmarks/bench_frame_api.py --bar-frames 2,3``): the files' CPU time is only moved, OpenEXR's writer holds
the GIL for the whole write (measured: a spinning Python thread got 2 % of its rate meanwhile), and a writer
*process* at low priority was slower still (5.38 s: start-up and the arrays sent through a pipe; tried, not kept).
It overlaps where the renderer leaves the CPU idle (a GPU variant).
"""

from __future__ import annotations

import queue
import threading

from renderlab.files.signals import deferred

_STOP = object()


class BackgroundJobs:
    """One worker thread running submitted callables in submission order.

    Parameters
    ----------
    depth : int
        Jobs that may wait while one runs; :meth:`submit` blocks beyond that.
    name : str
        The thread's name.
    """

    def __init__(self, depth: int = 1, name: str = "renderlab-writer"):
        if depth < 1:
            raise ValueError(f"depth must be at least 1, got {depth}")
        self._q: queue.Queue = queue.Queue(maxsize=int(depth))
        self._error: BaseException | None = None
        self._closed = False
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while True:
            job = self._q.get()
            try:
                if job is _STOP:
                    return
                if self._error is None:  # after a failure the rest is skipped (the set is not committed)
                    job()
            except BaseException as exc:  # noqa: BLE001 (kept and raised in the caller's thread)
                self._error = exc
            finally:
                self._q.task_done()

    def check(self) -> None:
        """Raise the first error of a finished job (once)."""
        if isinstance(self._error, BaseException):
            exc, self._error = self._error, _Reported(self._error)
            raise exc

    def submit(self, job) -> None:
        """Queue ``job`` (a callable without arguments); blocks while ``depth`` jobs wait. Raises an earlier
        job's error instead of queueing."""
        if self._closed:
            raise RuntimeError("BackgroundJobs is closed")
        self.check()
        with deferred():  # a signal inside put would leave the queue's lock taken (signals.deferred)
            self._q.put(job)

    def flush(self) -> None:
        """Wait until every queued job has run, then raise the first error among them."""
        if not self._closed:
            with deferred():
                self._q.join()
        self.check()

    def close(self, cancel: bool = False) -> None:
        """Stop the thread after the queued jobs (``cancel``: after the running one only) and wait for it.
        Raises a job's error unless ``cancel`` (the caller is already handling one)."""
        if self._closed:
            return
        with deferred():  # the queue's lock is never left taken by a signal (signals.deferred)
            if cancel:
                while True:
                    try:
                        self._q.get_nowait()
                    except queue.Empty:
                        break
                    self._q.task_done()
            self._q.put(_STOP)
            self._thread.join()
            self._closed = True
        if not cancel:
            self.check()


class _Reported:
    """An error already raised once: later checks pass (the caller handles the first raise)."""

    def __init__(self, exc: BaseException):
        self.exc = exc

