"""Executors: where the runs of a campaign execute.

* :class:`InProcessExecutor` — one run after another in this process (debugging, ``--workers 0``).
* :class:`DaskExecutor` — a Dask ``LocalCluster`` sized to the machine (one single-threaded worker
  process per core, or ``--workers N``), or an existing cluster (``--scheduler ADDRESS``; e.g. one
  started by dask-jobqueue on SLURM/PBS). Dask is imported only here, inside the functions.

Every executor calls :func:`execute_run`, which runs the study, validates its tables and writes the
run's folder itself (so finished runs survive a killed driver), and never raises: a failing run
records its error and the campaign goes on; a run that fails because of the machine (a full or
read-only disk: ``env_errno``) lets the runner stop the campaign and say so.

Network steps are bounded: ``--scheduler`` is probed (connect, handshake and first answer within
``--connect-timeout``) before the Dask client starts; ``tls://`` addresses take a CA file and an
optional client certificate and key. Dask's protocol pickles: trust the scheduler you name.
"""

from __future__ import annotations

import math
import os
import re
import time
import traceback
from pathlib import Path

from renderlab import plugins
from renderlab.campaign import store
from renderlab.contracts.schemas import TIMING_COLUMNS, core_schema, kind_of_table_name, table_kind
from renderlab.errors import UserError
from renderlab.extras import require
from renderlab.files.signals import ignored_in_children
from renderlab.scenario import scenario_from_dict


def _validate_tables(tables, task) -> dict:
    import pyarrow as pa


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
        named = kind_of_table_name(name)  # a name a registered kind claims (measurements: landmark)
        if named is not None and table_kind(t) != named:
            missing = [c for c in core_schema(named).names if c not in t.column_names]
            raise ValueError(f"study {task.study}: {name} lack columns {', '.join(missing)}")
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


#: errno names of failures that come from the machine, not the run (a full or read-only disk, no memory)
ENVIRONMENT_ERRNOS = ("ENOSPC", "EDQUOT", "EROFS", "EIO", "ENOMEM")
_ENV_TEXT = {"No space left on device": "ENOSPC", "Disk quota exceeded": "EDQUOT",
             "Read-only file system": "EROFS", "Input/output error": "EIO"}


def environment_errno(exc: BaseException) -> str:
    """The errno name (``"ENOSPC"``, ...) when ``exc`` or an exception it came from is an environment failure
    (also a UserError whose message carries the system's text), else ``""``."""
    import errno

    seen = 0
    while exc is not None and seen < 8:
        code = errno.errorcode.get(getattr(exc, "errno", None) or -1, "")
        if code in ENVIRONMENT_ERRNOS:
            return code
        if isinstance(exc, MemoryError):
            return "ENOMEM"
        for text, name in _ENV_TEXT.items():
            if text in str(exc):
                return name
        exc, seen = exc.__cause__ or exc.__context__, seen + 1
    return ""


def split_timings(tables: dict) -> tuple[dict, "object | None"]:
    """Result tables with every timing column set to NaN, and one ``timings`` table holding the values
    (``table``, ``row`` and the columns), or None when no table has one (``--timings separate``)."""
    import pyarrow as pa


    out, parts = {}, []
    for name, t in sorted(tables.items()):
        cols = [c for c in t.column_names if c in TIMING_COLUMNS or (c.startswith("t_") and c.endswith("_ms"))]
        for c in cols:
            parts.append(pa.table({"table": pa.array([name] * t.num_rows, pa.string()),
                                   "row": pa.array(range(t.num_rows), pa.int64()),
                                   "column": pa.array([c] * t.num_rows, pa.string()),
                                   "value": t.column(c).cast(pa.float64())}))
            t = t.set_column(t.column_names.index(c), c, pa.array([math.nan] * t.num_rows, pa.float64()))
        out[name] = t
    return out, (pa.concat_tables(parts) if parts else None)


def execute_run(task, timings: str = "inline") -> dict:
    """Execute one run (a :class:`renderlab.campaign.plan.RunTask`) and store it; return its status.

    ``timings="separate"`` blanks (NaN) the timing columns of the result tables and writes them to the run's
    ``timings.parquet`` (so the same seed gives byte-identical result tables). A failure to store the run
    (a full or read-only disk) is returned, not raised, with ``env_errno`` set.
    """
    apply_thread_limit()
    t0 = time.perf_counter()
    status = {"run": task.index, "status": "ok", "error": "", "seconds": 0.0}
    tables, side = {}, None
    try:
        for registry, name, ref in task.plugins:  # typed by the user on the command line, never read from a file
            plugins.registry(registry).add_reference(ref, name)
        fn = plugins.studies.get(task.study, where="campaign.study: ").run
        scenario = scenario_from_dict(task.scenario, "campaign scenario")
        workdir = Path(task.campaign_dir) / "work"
        tables = _validate_tables(fn(scenario, Path(task.base_dir), task.index, task.seed_sequence(), workdir), task)
        if timings == "separate":
            tables, side = split_timings(tables)
    except Exception as exc:  # noqa: BLE001 - a failing run is recorded, the campaign goes on
        tables = {}
        status["status"] = "error"
        status["error"] = f"{type(exc).__name__}: {' '.join(str(exc).split())}"
        if environment_errno(exc):
            status["env_errno"] = environment_errno(exc)
        if not isinstance(exc, UserError):
            status["traceback"] = traceback.format_exc(limit=8)
    status["seconds"] = round(time.perf_counter() - t0, 3)
    try:
        store.write_run(Path(task.campaign_dir), task.index, tables, status)
        if side is not None:
            _write_timings(store.run_dir(Path(task.campaign_dir), task.index), side)
    except OSError as exc:
        return {**status, "status": "error", "error": f"cannot store run {task.index}: {exc.strerror or exc}",
                "env_errno": environment_errno(exc) or "EIO"}
    return status


def _write_timings(folder: Path, table) -> None:
    import pyarrow.parquet as pq

    tmp = folder / f".timings.parquet.{os.getpid()}-{os.urandom(4).hex()}"
    try:
        pq.write_table(table, str(tmp))
        os.replace(tmp, folder / "timings.parquet")
    finally:
        if tmp.exists():
            tmp.unlink()


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


_ADDRESS = re.compile(r"^(?:(?P<scheme>[A-Za-z][A-Za-z0-9+.-]*)://)?(?P<host>\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.-]+)"
                      r":(?P<port>[0-9]{1,5})$")
#: at most this many local workers per usable core
WORKERS_PER_CORE = 4


def check_workers(workers: int | None) -> None:
    """Refuse ``--workers`` beyond :data:`WORKERS_PER_CORE` × the usable cores (each is a process)."""
    limit = WORKERS_PER_CORE * default_workers()
    if workers is not None and workers > limit:
        raise UserError(f"--workers {workers} is more than {WORKERS_PER_CORE} per core ({limit} on this machine, "
                        f"{default_workers()} cores); each worker is a process")


def check_scheduler_options(address: str | None, ca_file=None, cert=None, key=None):
    """Check ``--scheduler`` and ``--tls-*``: ``[tcp://]HOST:PORT`` or ``tls://HOST:PORT`` with a CA file (and a
    client certificate and key together). Returns a ``distributed.security.Security`` for tls://, else None."""
    tls_opts = [f for f in (ca_file, cert, key) if f]
    if address is None:
        if tls_opts:
            raise UserError("--tls-ca-file, --tls-cert and --tls-key need --scheduler tls://HOST:PORT")
        return None
    m = _ADDRESS.match(address.strip())
    if not m or not 1 <= int(m["port"]) <= 65535:
        raise UserError(f"--scheduler {address[:200]!r}: expected tcp://HOST:PORT or tls://HOST:PORT")
    scheme = (m["scheme"] or "tcp").lower()
    if scheme not in ("tcp", "tls"):
        raise UserError(f"--scheduler {address[:200]!r}: scheme must be tcp:// or tls://, not {scheme}://")
    if scheme == "tcp":
        if tls_opts:
            raise UserError("--tls-ca-file, --tls-cert and --tls-key need a tls:// scheduler address")
        return None
    if not ca_file:
        raise UserError("a tls:// scheduler needs --tls-ca-file (the CA certificate that signed the scheduler's)")
    if bool(cert) != bool(key):
        raise UserError("--tls-cert and --tls-key go together")
    for flag, f in (("--tls-ca-file", ca_file), ("--tls-cert", cert), ("--tls-key", key)):
        if f and not (os.path.isfile(f) and os.access(f, os.R_OK)):
            raise UserError(f"{flag} {f}: not a readable file")
    from distributed.security import Security

    try:
        sec = Security(tls_ca_file=ca_file, tls_client_cert=cert, tls_client_key=key, require_encryption=True)
        sec.get_connection_args("client")  # loads the files: a bad certificate or key fails here
    except Exception as exc:  # noqa: BLE001 - ssl errors of the user's files
        raise UserError(f"TLS options: {' '.join(str(exc).split()) or type(exc).__name__}") from None
    return sec


def probe_scheduler(address: str, timeout_s: float, security=None) -> dict:
    """Connect to ``address`` and ask for its identity, all within ``timeout_s`` + 0.5 s (connect, handshake and
    first answer: a peer that accepts and never answers fails in time). Returns the identity.

    Raises
    ------
    UserError
        Nothing answered in time, the connection failed, or the peer is not a Dask scheduler.
    """
    import asyncio

    from distributed.comm import connect

    args = security.get_connection_args("client") if security is not None else {}

    async def ask():
        comm = await connect(address, timeout=timeout_s, deserialize=False, **args)
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    try:
        reply = asyncio.run(asyncio.wait_for(ask(), timeout_s + 0.5))  # connect's own bound ends first
    except asyncio.TimeoutError:
        raise UserError(f"Dask scheduler at {address} did not answer within {timeout_s:g} s "
                        "(--connect-timeout)") from None
    except MemoryError:  # a peer sending garbage: Dask read a frame length of exabytes
        raise UserError(f"{address} answered, but not in Dask's protocol (not a Dask scheduler)") from None
    except Exception as exc:  # noqa: BLE001 - any failure to connect is the user's address
        raise UserError(f"cannot reach Dask scheduler at {address}: "
                        f"{' '.join(str(exc).split()) or type(exc).__name__}") from None
    if not isinstance(reply, dict) or reply.get("type") != "Scheduler":
        raise UserError(f"{address} answered, but not as a Dask scheduler")
    return reply


class DaskExecutor:
    """Dask distributed: a LocalCluster of ``workers`` single-threaded processes, or ``scheduler``.

    A scheduler is probed first (:func:`probe_scheduler`: connect and first answer within
    ``connect_timeout_s``); ``security`` (``distributed.security.Security``) is for tls:// addresses. Dask's
    protocol pickles: a scheduler can run code in this process, so connect only to one you trust. Local
    workers start with SIGINT/SIGHUP ignored (the driver handles them and closes the cluster), scheduler, workers
    and the scheduler's HTTP endpoint listen on 127.0.0.1 only (no dashboard), and keep their scratch space under
    ``$DASK_TEMPORARY_DIRECTORY`` (the lab cache). The local cluster is single-user: Dask offers no authentication
    for it short of TLS certificates, so a local user of a shared host could submit work while it runs (README).
    """

    name = "dask"

    def __init__(self, workers: int | None = None, scheduler: str | None = None, connect_timeout_s: float = 10.0,
                 threads_per_run: int | None = None, security=None):
        if workers is not None and scheduler is not None:
            raise UserError("give either --workers or --scheduler, not both")
        check_workers(workers)
        self.workers = workers or default_workers()
        self.threads_per_run = threads_per_run or max(1, default_workers() // self.workers)
        self.scheduler = scheduler
        self.connect_timeout_s = connect_timeout_s
        self.security = security
        self._cluster = self._client = None

    def __enter__(self):
        import logging

        from distributed import Client, LocalCluster


        logging.getLogger("distributed").setLevel(logging.CRITICAL)
        if self.scheduler:
            probe_scheduler(self.scheduler, self.connect_timeout_s, self.security)
            try:
                self._client = Client(self.scheduler, timeout=f"{self.connect_timeout_s}s", security=self.security)
            except Exception as exc:  # noqa: BLE001 - any failure to connect is the user's address
                raise UserError(f"cannot reach Dask scheduler at {self.scheduler}: "
                                f"{' '.join(str(exc).split()) or type(exc).__name__}") from None
            self.workers = max(1, len(self._client.scheduler_info().get("workers", {})))
        else:
            scratch = os.environ.get("DASK_TEMPORARY_DIRECTORY") or None
            _quiet_resource_tracker()
            with ignored_in_children():
                self._cluster = LocalCluster(n_workers=self.workers, threads_per_worker=1, processes=True,
                                             host="127.0.0.1", dashboard_address=None, silence_logs=logging.CRITICAL,
                                             scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
                                             env=thread_env(self.threads_per_run), local_directory=scratch)
                self._client = Client(self._cluster)
        return self

    def __exit__(self, *exc):
        client, cluster, self._client, self._cluster = self._client, self._cluster, None, None
        try:
            if client is not None:
                client.close(timeout=self.connect_timeout_s)
        finally:
            if cluster is not None:
                cluster.close(timeout=30)
        return False

    def map_unordered(self, fn, tasks):
        from distributed import as_completed

        futures = self._client.map(fn, list(tasks), pure=False)
        for fut in as_completed(futures):
            yield fut.result()


_QUIET_TRACKER = "ignore::UserWarning:multiprocessing.resource_tracker"


def _quiet_resource_tracker() -> None:
    """Keep multiprocessing's resource tracker (started with the first worker) from printing its "leaked
    semaphore" warnings after an interrupted campaign (workers killed mid-run; it cleans them up anyway)."""
    current = os.environ.get("PYTHONWARNINGS", "")
    if _QUIET_TRACKER not in current:
        os.environ["PYTHONWARNINGS"] = ",".join(filter(None, [current, _QUIET_TRACKER]))


def make_executor(workers: int | None = None, scheduler: str | None = None, connect_timeout_s: float = 10.0,
                  security=None):
    """``workers == 0`` → in-process; otherwise Dask (LocalCluster of ``workers`` or the machine's cores,
    or the cluster at ``scheduler``, tls:// with ``security``)."""
    if workers == 0 and scheduler is None:
        return InProcessExecutor()

    require("distributed", "cluster", hint="--workers 0 runs the campaign in this process")
    return DaskExecutor(workers=workers, scheduler=scheduler, connect_timeout_s=connect_timeout_s, security=security)
