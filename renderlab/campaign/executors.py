"""Executors: where the runs of a campaign execute.

* :class:`InProcessExecutor` — one run after another in this process (debugging, ``--workers 0``).
* :class:`DaskExecutor` — a Dask ``LocalCluster`` sized to the machine (one single-threaded worker
  process per core, or ``--workers N``), or an existing cluster (``--scheduler ADDRESS``; e.g. one
  started by dask-jobqueue on SLURM/PBS). Dask is imported only here, inside the functions.

Every executor calls :func:`execute_run`, which runs the study, validates its tables and writes the
run's folder itself (so finished runs survive a killed driver), and never raises: a failing run
records its error and the campaign goes on.
"""

from __future__ import annotations

import os
import time
import traceback
from pathlib import Path

from renderlab.errors import UserError


def _validate_tables(tables, task) -> dict:
    import pyarrow as pa

    from renderlab.contracts.schemas import CORE, table_kind

    if not isinstance(tables, dict) or not tables:
        raise TypeError(f"study {task.study} returned {type(tables).__name__}, expected a non-empty dict of tables")
    out = {}
    for name, t in tables.items():
        if not isinstance(name, str) or not name.isidentifier():
            raise ValueError(f"study {task.study}: table name {name!r} is not an identifier")
        if not isinstance(t, pa.Table):
            raise TypeError(f"study {task.study}: table {name} is {type(t).__name__}, not pyarrow.Table")
        if "run" not in t.column_names:
            t = t.add_column(0, "run", pa.array([task.index] * t.num_rows, pa.int64()))
        if "campaign" not in t.column_names:
            t = t.add_column(0, "campaign", pa.array([task.campaign] * t.num_rows, pa.string()))
        if name == "measurements" and table_kind(t) != "landmark":
            missing = [c for c in CORE["landmark"].names if c not in t.column_names]
            raise ValueError(f"study {task.study}: measurements lack columns {', '.join(missing)}")
        out[name] = t
    return out


THREAD_ENV = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")
_thread_limit_applied: list[int] = []


def thread_env(threads: int) -> dict[str, str]:
    """Worker environment capping every thread pool of a run at ``threads``."""
    t = str(max(1, int(threads)))
    return {"RENDERLAB_THREADS": t, **{k: t for k in THREAD_ENV}}


def apply_thread_limit() -> int | None:
    """Cap Dr.Jit's thread pool (Mitsuba) and numba at ``$RENDERLAB_THREADS`` in this process (once).

    BLAS/OpenMP read their variables at start-up; the worker's environment already holds them.
    Returns the limit, or None when the variable is not set (the in-process executor: all cores).
    """
    raw = os.environ.get("RENDERLAB_THREADS", "")
    if not raw.isdigit() or int(raw) < 1:
        return None
    n = int(raw)
    if n not in _thread_limit_applied:
        import drjit as dr

        dr.set_thread_count(n)
        try:
            import numba

            numba.set_num_threads(min(n, numba.config.NUMBA_NUM_THREADS))
        except ImportError:  # pragma: no cover - numba is a dependency
            pass
        _thread_limit_applied.append(n)
    return n


def thread_report(_=None) -> dict:
    """This process's thread limits after :func:`apply_thread_limit` (for diagnostics and tests)."""
    import drjit as dr
    import numba

    return {"limit": apply_thread_limit(), "drjit": int(dr.thread_count()), "numba": int(numba.get_num_threads()),
            **{k: os.environ.get(k) for k in THREAD_ENV}}


def execute_run(task) -> dict:
    """Execute one run (a :class:`renderlab.campaign.plan.RunTask`) and store it; return its status."""
    from renderlab.campaign import store
    from renderlab import plugins
    from renderlab.scenario import scenario_from_dict

    apply_thread_limit()
    t0 = time.perf_counter()
    status = {"run": task.index, "status": "ok", "error": "", "seconds": 0.0}
    tables = {}
    try:
        for registry, name, ref in task.plugins:  # typed by the user on the command line, never read from a file
            plugins.REGISTRIES[registry].add_reference(ref, name)
        fn = plugins.studies.get(task.study, where="campaign.study: ").run
        scenario = scenario_from_dict(task.scenario, "campaign scenario")
        workdir = Path(task.campaign_dir) / "work"
        tables = _validate_tables(fn(scenario, Path(task.base_dir), task.index, task.seed_sequence(), workdir), task)
    except Exception as exc:  # noqa: BLE001 - a failing run is recorded, the campaign goes on
        tables = {}
        status["status"] = "error"
        status["error"] = f"{type(exc).__name__}: {' '.join(str(exc).split())}"
        if not isinstance(exc, UserError):
            status["traceback"] = traceback.format_exc(limit=8)
    status["seconds"] = round(time.perf_counter() - t0, 3)
    store.write_run(Path(task.campaign_dir), task.index, tables, status)
    return status


class InProcessExecutor:
    """Runs tasks one after another in this process."""

    name = "in-process"
    workers = 1

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def map_unordered(self, fn, tasks):
        for task in tasks:
            yield fn(task)


def default_workers() -> int:
    """One worker per usable core."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


class DaskExecutor:
    """Dask distributed: a LocalCluster of ``workers`` single-threaded processes, or ``scheduler``."""

    name = "dask"

    def __init__(self, workers: int | None = None, scheduler: str | None = None, connect_timeout_s: float = 10.0,
                 threads_per_run: int | None = None):
        if workers is not None and scheduler is not None:
            raise UserError("give either --workers or --scheduler, not both")
        self.workers = workers or default_workers()
        self.threads_per_run = threads_per_run or max(1, default_workers() // self.workers)
        self.scheduler = scheduler
        self.connect_timeout_s = connect_timeout_s
        self._cluster = self._client = None

    def __enter__(self):
        import logging

        from distributed import Client, LocalCluster

        logging.getLogger("distributed").setLevel(logging.ERROR)
        if self.scheduler:
            try:
                self._client = Client(self.scheduler, timeout=f"{self.connect_timeout_s}s")
            except Exception as exc:  # noqa: BLE001 - any failure to connect is the user's address
                raise UserError(f"cannot reach Dask scheduler at {self.scheduler}: "
                                f"{' '.join(str(exc).split()) or type(exc).__name__}") from None
            self.workers = max(1, len(self._client.scheduler_info().get("workers", {})))
        else:
            self._cluster = LocalCluster(n_workers=self.workers, threads_per_worker=1, processes=True,
                                         dashboard_address=None, silence_logs=logging.ERROR,
                                         env=thread_env(self.threads_per_run))
            self._client = Client(self._cluster)
        return self

    def __exit__(self, *exc):
        if self._client is not None:
            self._client.close()
        if self._cluster is not None:
            self._cluster.close()
        self._client = self._cluster = None
        return False

    def map_unordered(self, fn, tasks):
        from distributed import as_completed

        futures = self._client.map(fn, list(tasks), pure=False)
        for fut in as_completed(futures):
            yield fut.result()


def make_executor(workers: int | None = None, scheduler: str | None = None, connect_timeout_s: float = 10.0):
    """``workers == 0`` → in-process; otherwise Dask (LocalCluster of ``workers`` or the machine's cores,
    or the cluster at ``scheduler``)."""
    if workers == 0 and scheduler is None:
        return InProcessExecutor()
    from renderlab.extras import require

    require("distributed", "cluster", hint="--workers 0 runs the campaign in this process")
    return DaskExecutor(workers=workers, scheduler=scheduler, connect_timeout_s=connect_timeout_s)
