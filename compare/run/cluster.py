"""Running a suite's cases on a Dask cluster (``xval run --scheduler``).

Only the executor changes. The runner submits the same tasks a local run
gives its case hosts (one :func:`~compare.run.runner.solve_reference` per scene, one
:func:`~compare.run.isolation.execute` per case); a Dask worker runs each in its
own case host, a child forked from the worker, so timeouts and a case that
kills its process behave exactly as locally. Results come back to the client,
which computes the metrics and writes the records case by case, so
``--resume`` and the statuses are unchanged.

Details: docs/running.md, "Module notes", ``compare/run/cluster.py``.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import json
import logging
import math
import multiprocessing
import re
import sys
import threading
import time
import uuid
from collections import deque
from dataclasses import dataclass, field
from typing import Any, Callable, Iterator

from engines.errors import UserError

from compare.run.runner import MAX_ATTEMPTS, RunStopped, default_jobs

#: What to install when dask is missing.
INSTALL_HINT = "pip install 'xval[dask]'"
#: s to wait for the scheduler to answer, and for a first worker to join it.
CONNECT_TIMEOUT = 10.0
WORKER_TIMEOUT = 60.0
#: Scheduler settings of ``--scheduler local``: a case that kills its worker
#: is tried MAX_ATTEMPTS times in all, as with the local pool (Dask's default
#: is 4). That only the case, not others queued with it, pays for a dead
#: worker is DaskExecutor's doing.
LOCAL_SCHEDULER_CONFIG = {"distributed.scheduler.allowed-failures": MAX_ATTEMPTS - 1}


class SchedulerLost(RunStopped):
    """The client lost its connection to the scheduler: the run stops, finished cases stay on disk."""


class WorkerDied(Exception):
    """The Dask worker process running a task died (every allowed attempt); the runner records the case as failed."""


def import_distributed() -> Any:
    """``distributed``, or a UserError saying how to install it."""
    try:
        import distributed
    except ImportError:
        raise UserError(
            f"--scheduler needs Dask's distributed scheduler, which is not installed; install it with: {INSTALL_HINT}"
        ) from None
    return distributed


@dataclass(frozen=True)
class SchedulerSpec:
    """A parsed ``--scheduler``: a scheduler's ``address``, or (address None) a local cluster of ``workers``."""

    address: str | None
    workers: int | None = None


_LOCAL = re.compile(r"local(?::(?P<n>\d+))?")
_ADDRESS = re.compile(r"([a-z][a-z0-9+.-]*://)?[^\s:/]+:\d+/?")


def parse_scheduler(text: str) -> SchedulerSpec:
    """``tcp://HOST:PORT`` (or ``HOST:PORT``) -> that scheduler; ``local`` / ``local:N`` -> a LocalCluster."""
    text = text.strip()
    local = _LOCAL.fullmatch(text)
    if local:
        n = local.group("n")
        if n is not None and int(n) < 1:
            raise UserError(f"--scheduler: {text!r} asks for no workers; use local:N with N >= 1")
        return SchedulerSpec(None, int(n) if n else None)
    if not _ADDRESS.fullmatch(text):
        raise UserError(f"--scheduler: expected tcp://HOST:PORT or local[:N], got {text!r}")
    return SchedulerSpec(text)


# --- the worker side ------------------------------------------------------------------------------

_prepared = threading.Lock()
_PREPARED = False


def _prepare_worker() -> None:
    """Make this Dask worker process able to host cases (once per process)."""
    global _PREPARED
    with _prepared:
        if _PREPARED:
            return
        # The nanny starts workers as daemonic processes, and multiprocessing
        # refuses to let a daemonic process start a child, which the case host
        # is. The flag only makes multiprocessing kill daemonic children at
        # exit; the case hosts are daemonic themselves and also end when this
        # worker's pipe closes, so clearing it loses nothing.
        multiprocessing.current_process()._config["daemon"] = False  # type: ignore[attr-defined]
        # Import every engine now, so that case hosts forked from this worker
        # inherit them rather than each importing numba, MuJoCo and PyBullet.
        from compare.run import environment

        environment.engine_versions()
        _PREPARED = True


def run_on_worker(fn: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
    """What a Dask worker runs for each submitted task: ``fn(*args, **kwargs)`` once the worker is prepared."""
    _prepare_worker()
    return fn(*args, **kwargs)


def software() -> dict[str, Any]:
    """This process's xval, Python, numpy and engine versions: what must match between client and workers."""
    import numpy as np

    from compare.run import environment, runner

    return {
        "xval": runner.compare_version(),
        "python": sys.version.split()[0],
        "numpy": np.__version__,
        "engines": environment.engine_versions(),
    }


def _flatten(sw: dict[str, Any]) -> dict[str, str]:
    flat = {k: str(v) for k, v in sw.items() if k != "engines"}
    flat.update({name: str(v) for name, v in sw.get("engines", {}).items()})
    return flat


def version_mismatches(client: dict[str, Any], workers: dict[str, dict[str, Any]]) -> list[str]:
    """One line per worker whose software (see :func:`software`) differs from the client's, naming each difference."""
    ours = _flatten(client)
    lines = []
    for address, sw in sorted(workers.items()):
        theirs = _flatten(sw)
        diffs = [
            f"{name} {theirs.get(name, 'missing')} (here {ours.get(name, 'missing')})"
            for name in sorted(set(ours) | set(theirs))
            if theirs.get(name) != ours.get(name)
        ]
        if diffs:
            lines.append(f"worker {address} runs {', '.join(diffs)}; its results are not comparable with this machine's")
    return lines


def _group_by_software(workers: dict[str, dict[str, Any]]) -> list[dict[str, Any]]:
    """The distinct software of the workers, each with the workers that run it (compact for 100 workers)."""
    groups: dict[str, dict[str, Any]] = {}
    for address, sw in sorted(workers.items()):
        group = groups.setdefault(json.dumps(sw, sort_keys=True), {"workers": [], **sw})
        group["workers"].append(address)
    return list(groups.values())


# --- the client side ------------------------------------------------------------------------------


def _task_name(fn: Callable[..., Any], args: tuple[Any, ...]) -> str:
    """``execute bead|mujoco/hinge|dt=0.01`` or ``solve_reference bead``: what the dashboard shows."""
    first = args[0] if args else None
    # A ReferenceTask has a name (its scene's); a CaseTask has none, only its case id.
    label = getattr(first, "name", None) or getattr(first, "case_id", None) or ""
    return f"{getattr(fn, '__name__', 'task')} {label}".strip()


class DaskExecutor(cf.Executor):
    """A concurrent.futures Executor whose tasks run on a Dask cluster (why not ``get_executor``:
    docs/running.md, "Module notes").

    At most one task per worker thread is on the cluster at a time; the rest
    wait here. Dask would otherwise hand a worker several tasks at once (it
    queues only large groups of alike tasks), and when a worker process dies
    the scheduler counts every task it held as a suspect: an innocent case
    queued behind one that kills its worker would be failed with it.
    """

    #: s between refreshes of the cluster's thread count (workers come and go).
    CAPACITY_REFRESH = 2.0

    def __init__(self, client: Any) -> None:
        self.client = client
        self.address = client.scheduler.address
        self._lock = threading.RLock()
        self._remote: dict[cf.Future, Any] = {}  # sent to the cluster, not yet settled
        self._waiting: deque[tuple[cf.Future, Callable[..., Any], tuple, dict]] = deque()
        self._capacity = 1
        self._capacity_checked = -math.inf
        self._closed = False

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> cf.Future:
        local: cf.Future = cf.Future()
        local.set_running_or_notify_cancel()  # queued for the cluster: only the scheduler may still cancel it
        with self._lock:
            if self._closed:
                raise RuntimeError("cannot schedule new futures after shutdown")
            self._waiting.append((local, fn, args, kwargs))
        self._pump()
        return local

    def capacity(self) -> int:
        """Threads of the cluster's workers (at least 1), refreshed every CAPACITY_REFRESH s."""
        if time.monotonic() - self._capacity_checked > self.CAPACITY_REFRESH:
            with contextlib.suppress(Exception):  # a lost connection is reported by the futures
                self._capacity = max(1, sum(self.client.nthreads().values()))
            self._capacity_checked = time.monotonic()
        return self._capacity

    def _pump(self) -> None:
        """Send waiting tasks while the cluster has a free thread."""
        with self._lock:
            while self._waiting and not self._closed and len(self._remote) < self.capacity():
                local, fn, args, kwargs = self._waiting.popleft()
                if self.client.status != "running":
                    local.set_exception(self._lost())
                    continue
                key = f"{_task_name(fn, args)} {uuid.uuid4().hex[:8]}"  # unique: a resubmitted case is a new task
                remote = self.client.submit(run_on_worker, fn, *args, key=key, pure=False, **kwargs)
                self._remote[local] = remote
                remote.add_done_callback(lambda done, local=local: self._settle(local, done))

    def _lost(self) -> SchedulerLost:
        return SchedulerLost(f"lost the connection to the Dask scheduler at {self.address}")

    def _settle(self, local: cf.Future, remote: Any) -> None:
        """Runs in Dask's callback thread: fetch the result (or the reason there is none) into ``local``."""
        from distributed import KilledWorker

        try:
            local.set_result(remote.result())
        except KilledWorker as exc:
            attempts = exc.allowed_failures + 1
            local.set_exception(WorkerDied(
                f"the Dask worker process running it died ({attempts} attempt{'s' if attempts > 1 else ''}, "
                f"the last on {exc.last_worker.address})"
            ))
        except BaseException as exc:  # noqa: BLE001 - every outcome must reach the runner
            if self.client.status != "running" or isinstance(exc, cf.CancelledError):
                local.set_exception(self._lost())  # Dask cancels every future when the connection drops
            else:
                local.set_exception(exc)  # the task itself raised
        finally:
            with self._lock:
                self._remote.pop(local, None)
            remote.release()  # the worker may now free the result
        self._pump()

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        with self._lock:
            self._closed = True
            if cancel_futures:
                self._waiting.clear()
            pending = dict(self._remote)
        if cancel_futures and pending and self.client.status == "running":
            with contextlib.suppress(Exception):
                self.client.cancel(list(pending.values()))
        if wait:
            cf.wait(list(pending) + [w[0] for w in self._waiting])


@dataclass
class Cluster:
    """A connection to a Dask cluster for one run.

    executor : what the runner submits to.
    metadata : run.json's ``environment["cluster"]``: scheduler address,
        whether it is a local cluster, workers, threads, the workers'
        software grouped, and the mismatches with this machine.
    warnings : one line per worker whose software differs from this machine's.
    """

    executor: DaskExecutor
    metadata: dict[str, Any]
    warnings: list[str] = field(default_factory=list)


def start_local_cluster(workers: int) -> Any:
    """An in-process LocalCluster of ``workers`` processes of one thread each (the case hosts are the parallelism)."""
    distributed = import_distributed()
    import dask

    with dask.config.set(LOCAL_SCHEDULER_CONFIG):
        return distributed.LocalCluster(
            n_workers=workers, threads_per_worker=1, processes=True,
            # What its scheduler and nannies would log (a worker restarted, a task
            # failed because workers died) is in the case records and progress lines.
            silence_logs=logging.CRITICAL,
            dashboard_address=":0",  # any free port: two runs at once must not fight over 8787
        )


def _connect(address: str, timeout: float) -> Any:
    distributed = import_distributed()
    try:
        return distributed.Client(address, timeout=timeout, set_as_default=False)
    except (OSError, ValueError) as exc:
        raise UserError(
            f"--scheduler: cannot reach a Dask scheduler at {address} ({str(exc).splitlines()[0]}); "
            f"start one with 'dask scheduler' or check the address"
        ) from None


def describe(client: Any, local: bool) -> tuple[dict[str, Any], list[str]]:
    """The cluster's metadata for run.json, and the mismatch warnings (see :class:`Cluster`)."""
    import distributed

    try:
        workers = client.run(software)
    except Exception as exc:  # e.g. xval not installed on a worker: unpickling software() fails there
        raise UserError(
            f"--scheduler: a Dask worker could not report its xval and engine versions "
            f"({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}); "
            f"install the same xval and engines on every worker"
        ) from None
    mismatches = version_mismatches(software(), workers)
    info = client.scheduler_info()
    metadata = {
        "scheduler": client.scheduler.address,
        "local_cluster": local,
        "dask": distributed.__version__,
        "workers": len(workers),
        "threads": sum(w.get("nthreads", 0) for w in info.get("workers", {}).values()),
        "worker_software": _group_by_software(workers),
        "mismatches": mismatches,
    }
    return metadata, mismatches


@contextlib.contextmanager
def connect(
    scheduler: str,
    *,
    jobs: int | None = None,
    connect_timeout: float = CONNECT_TIMEOUT,
    worker_timeout: float = WORKER_TIMEOUT,
) -> Iterator[Cluster]:
    """Connect to ``scheduler`` (``tcp://HOST:PORT`` or ``local[:N]``) for one run; closes everything it started.

    jobs : workers of ``local`` when it gives no N (all cores when None);
        refused with an address, whose workers decide the parallelism.
    UserError when dask is missing, the spec is malformed, the scheduler
    does not answer within ``connect_timeout`` s, no worker joins within
    ``worker_timeout`` s, or a worker cannot report its versions.
    """
    spec = parse_scheduler(scheduler)
    import_distributed()
    if spec.address is not None and jobs is not None:
        raise UserError("--jobs sets the local pool's processes; with --scheduler ADDRESS the workers' threads decide")
    with contextlib.ExitStack() as stack:
        # The client, and its batched sender ("Batched Comm Closed", at info level with the traceback), log
        # one when the scheduler goes away; SchedulerLost says it in one line.
        stack.enter_context(_quiet("distributed.client", "distributed.batched"))
        if spec.address is None:
            local = stack.enter_context(start_local_cluster(spec.workers or jobs or default_jobs()))
            address = local.scheduler_address
        else:
            address = spec.address
        client = _connect(address, connect_timeout)
        stack.callback(_close, client)
        try:
            client.wait_for_workers(1, timeout=worker_timeout)
        except TimeoutError:
            raise UserError(
                f"--scheduler: no Dask worker joined {address} within {worker_timeout:g} s; "
                f"start workers with: dask worker {address}"
            ) from None
        metadata, warnings = describe(client, local=spec.address is None)
        executor = DaskExecutor(client)
        stack.callback(executor.shutdown, wait=False, cancel_futures=True)
        yield Cluster(executor, metadata, warnings)


@contextlib.contextmanager
def _quiet(*logger_names: str) -> Iterator[None]:
    """Only critical messages from the loggers ``logger_names`` while the block runs."""
    loggers = [logging.getLogger(name) for name in logger_names]
    levels = [logger.level for logger in loggers]
    for logger in loggers:
        logger.setLevel(logging.CRITICAL)
    try:
        yield
    finally:
        for logger, level in zip(loggers, levels):
            logger.setLevel(level)


def _close(client: Any) -> None:
    # A client whose scheduler is gone would retry for its whole timeout; do not let that delay the exit.
    with contextlib.suppress(Exception):
        client.close(timeout=2)


def run_on_cluster(suite: Any, output: Any, scheduler: str, *, jobs: int | None = None,
                   warn: Callable[[str], None] = lambda line: None, **run_options: Any) -> Any:
    """``run_suite`` with the cases on the cluster ``scheduler``; ``warn`` gets each version-mismatch line.

    run_options : passed on to :func:`compare.run.runner.run_suite` (resume, timeout, progress).
    Raises SchedulerLost when the connection drops mid-run.
    """
    from compare.run.runner import run_suite

    with connect(scheduler, jobs=jobs) as cluster:
        for line in cluster.warnings:
            warn(line)
        return run_suite(suite, output, executor=cluster.executor,
                         environment_extra={"cluster": cluster.metadata}, **run_options)
