"""Signals and leftovers: SIGTERM and SIGHUP end a command the way Ctrl-C does, and staging folders of
earlier crashes are found and removed.

:func:`handled_signals` (installed by :func:`renderlab.cli.main`) turns SIGINT, SIGTERM and SIGHUP into
:class:`Terminated`, a :class:`KeyboardInterrupt`: it unwinds the stack through every ``finally`` and context
manager, so the truth-set writer, the campaign store and the executors remove their staging folders and
close their workers; the CLI then prints one line and exits with ``128 + signal`` (130, 143, 129). A second
signal while that clean-up runs is ignored; a third ends the process at once.

Every writer of the lab stages its output in a hidden sibling named ``.NAME.staging-PID-XXXXXXXX`` (or
``.NAME.old-PID-XXXXXXXX`` while replacing, ``.NAME.json.PID-XXXXXXXX`` for an atomic JSON write) and renames
it into place when complete. A ``kill -9`` leaves such folders; :func:`sweep_staging` removes those whose
process is gone (``--out``'s folder, a campaign's ``runs/`` and ``work/truth_cache/``, on the next run and on
``--resume``).
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import signal
import threading
from pathlib import Path

HANDLED = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
_STAGING = re.compile(r"^\.(?P<name>.+)\.(?:staging|old)-(?P<pid>\d+)-[0-9a-f]{8}$")
_JSON_TMP = re.compile(r"^\.(?P<name>.+\.json)\.(?P<pid>\d+)-[0-9a-f]{8}$")


class Terminated(KeyboardInterrupt):
    """Raised in the main thread by SIGINT, SIGTERM or SIGHUP; ``signum`` says which."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = int(signum)


_state = {"count": 0, "pending": None, "deferred": 0, "held": None}


def _handler(signum, frame):  # noqa: ARG001 - signal API
    _state["count"] += 1
    if _state["count"] == 1:
        _state["pending"] = int(signum)
        if _state["deferred"]:  # inside :func:`deferred`: the block's end raises it
            _state["held"] = int(signum)
        else:
            raise Terminated(signum)
    if _state["count"] >= 3:  # the user insists: no more clean-up
        os._exit(128 + signum)


@contextlib.contextmanager
def deferred():
    """Hold the first signal's :class:`Terminated` until the block ends (main thread; nestable).

    For blocks that take a lock another thread waits on (a ``queue.Queue`` shared with a writer thread): raised
    between a lock's acquire and the ``with`` that releases it, the exception would leave the lock taken and the
    clean-up that follows would wait on it for ever. A third signal still ends the process at once."""
    _state["deferred"] += 1
    try:
        yield
    finally:
        _state["deferred"] -= 1
    held = _state["held"]
    if held is not None and not _state["deferred"]:
        _state["held"] = _state["pending"] = None
        raise Terminated(held)


def raise_pending() -> None:
    """Raise :class:`Terminated` again for a signal whose first raise was swallowed, else do nothing.

    The handler raises wherever the main thread happens to be; when that is a weakref callback or ``__del__`` run by
    the garbage collector, Python prints "Exception ignored" and carries on, and the command would run to its end.
    Long loops (frames of a render, runs of a campaign) call this between items, so such a signal still ends the
    command at the next item. A raise that did propagate unwinds past these calls, so no signal is raised twice."""
    signum = _state.get("pending")
    if signum is not None:
        _state["pending"] = None
        raise Terminated(signum)


@contextlib.contextmanager
def handled_signals():
    """SIGINT/SIGTERM/SIGHUP raise :class:`Terminated` inside the block (main thread only; else a no-op)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = {s: signal.getsignal(s) for s in HANDLED}
    _state.update(count=0, pending=None, deferred=0, held=None)
    for s in HANDLED:
        signal.signal(s, _handler)
    try:
        yield
    finally:
        _state["pending"] = _state["held"] = None
        for s, h in old.items():
            signal.signal(s, h if h is not None else signal.SIG_DFL)


@contextlib.contextmanager
def ignored_in_children():
    """Ignore SIGINT and SIGHUP while worker processes are started inside the block, so they inherit the
    ignored disposition: a Ctrl-C (or a hang-up) reaches the whole process group, and the driver alone handles
    it and closes the workers, instead of every worker printing its own KeyboardInterrupt traceback. SIGTERM
    keeps its default in the workers (their supervisor terminates them with it)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    group = (signal.SIGINT, signal.SIGHUP)
    old = {s: signal.getsignal(s) for s in group}
    for s in group:
        signal.signal(s, signal.SIG_IGN)
    try:
        yield
    finally:
        _state["pending"] = None
        for s, h in old.items():
            signal.signal(s, h if h is not None else signal.SIG_DFL)


def exit_code(exc: BaseException) -> int:
    """``128 + signal`` for :class:`Terminated`, 130 for a plain KeyboardInterrupt."""
    return 128 + (exc.signum if isinstance(exc, Terminated) else int(signal.SIGINT))


def describe(exc: BaseException) -> str:
    """``"interrupted (SIGTERM)"`` and the like."""
    name = signal.Signals(exc.signum).name if isinstance(exc, Terminated) else "SIGINT"
    return f"interrupted ({name})"


def pid_alive(pid: int) -> bool:
    """Whether process ``pid`` exists on this machine."""
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, someone else's
        return True
    except OSError:
        return False
    return True


def staging_owner(name: str) -> tuple[str, int] | None:
    """``(target name, pid)`` of a staging/old/temporary entry name, or None for any other name."""
    m = _STAGING.match(name) or _JSON_TMP.match(name)
    return (m["name"], int(m["pid"])) if m else None


def sweep_staging(folder, target: str | None = None, *, own: bool = False) -> list[Path]:
    """Remove the leftover staging entries in ``folder`` whose process is gone (``own``: also this process's,
    when nothing in it writes any more); only those of ``target`` when given. Returns what was removed."""
    folder = Path(folder)
    removed = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for entry in entries:
        owner = staging_owner(entry.name)
        if owner is None or (target is not None and owner[0] != target):
            continue
        name, pid = owner
        if pid_alive(pid) and not (own and pid == os.getpid()):
            continue
        path = Path(entry.path)
        try:
            if entry.is_dir(follow_symlinks=False):
                shutil.rmtree(path)
            else:
                path.unlink()
            removed.append(path)
        except OSError:
            pass
    return removed


def sweep_campaign(campaign_dir, *, own: bool = False) -> list[Path]:
    """:func:`sweep_staging` of a campaign folder: its manifest's temporary files, ``runs/`` and
    ``work/truth_cache/``."""
    d = Path(campaign_dir)
    out = []
    for folder in (d, d / "runs", d / "work" / "truth_cache"):
        if folder.is_dir() and not folder.is_symlink():
            out += sweep_staging(folder, own=own)
    return out
