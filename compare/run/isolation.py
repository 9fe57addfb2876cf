"""Running one case so that whatever the engine does (raise, hang, segfault) only that case pays.

:func:`execute` is what the runner submits to its Executor. With
``isolate`` (the default) the case runs in a *case host*: a child process
forked from the worker (one per worker thread), which runs cases one after
another and answers each on a pipe. The worker waits at most ``timeout``
seconds for the answer:

- the engine raised: the host catches it and answers ``failed``;
- the host died (a segfault, ``os._exit``, SIGKILL): the pipe closes
  without an answer, the case is ``failed`` with the exit code or signal,
  and the next case gets a new host;
- no answer in time: the host is killed, the case is ``timeout``, and the
  next case gets a new host.

Because the worker itself never runs engine code, a case that kills its
process never breaks a ``ProcessPoolExecutor``. Reusing the host across
cases (rather than forking per case) matters for speed: a fork per case
cost 90–250 ms (copying a process that holds numba, MuJoCo and PyBullet,
and re-initializing them), more than most cases' stepping. It needs the
``fork`` start method (Linux, macOS); with ``isolate=False`` the case runs
in the worker itself (no timeout, and a crash breaks the pool, which the
runner then rebuilds).
"""

from __future__ import annotations

import contextlib
import multiprocessing
import signal
import threading
import time
import traceback
from dataclasses import dataclass, field
from typing import Any, Mapping

from engines.adapter import Engine
from engines.scene import Scene
from engines.trajectory import Trajectory


@dataclass(frozen=True)
class CaseTask:
    """Everything a worker needs to run one case (picklable).

    engine_id : ``name/variant`` or ``module:ATTRIBUTE/variant``, loaded in the worker.
    dt, sample_interval, timeout : s. repeats : runs whose stepping times are kept.
    """

    case_id: str
    engine_id: str
    variant: str | None
    options: Mapping[str, Any]
    scene: Scene
    dt: float
    sample_interval: float
    repeats: int = 1
    timeout: float = 120.0
    isolate: bool = True
    #: An outside program's spec (engines.command.spec_of), so any worker, here or on another machine, can run it.
    command: Mapping[str, Any] | None = None


@dataclass
class CaseOutcome:
    """What came back from one case.

    trajectory : the first run's Trajectory (its RunInfo holds the engine's
        own status), or None when the case failed or timed out outside the engine.
    wall_times : s, the stepping-loop wall time of each repeat.
    status, message : ``ok`` when the trajectory's status applies; else ``failed`` or ``timeout``.
    elapsed : s, wall time of the whole case (model building and all repeats).
    """

    case_id: str
    trajectory: Trajectory | None
    wall_times: list[float] = field(default_factory=list)
    status: str = "ok"
    message: str = ""
    elapsed: float = 0.0


def _engine_for(task: CaseTask) -> Engine:
    from engines.registry import load_engine  # here, not at import: loaded in the worker that runs the case

    if task.command is not None:
        from engines.command import adopt

        return adopt(task.command)
    return load_engine(task.engine_id)[0]


#: s a command engine's deadline leaves before the case's timeout, to kill its program's process
#: group and answer ``timeout`` before the worker kills the host (which would orphan the program).
COMMAND_MARGIN = 0.5


def simulate(task: CaseTask) -> CaseOutcome:
    """Run the case in this process: the first run gives the trajectory, every run a stepping time."""
    start = time.perf_counter()
    engine = _engine_for(task)
    first: Trajectory | None = None
    wall_times: list[float] = []
    with _command_deadline(task):
        for _ in range(task.repeats):
            trajectory = engine.simulate(
                task.scene, task.dt, variant=task.variant, options=task.options, sample_interval=task.sample_interval
            )
            wall_times.append(trajectory.info.wall_time)
            first = first or trajectory
            if trajectory.info.status != "ok":
                break  # repeating a failed or unstable run would only time the failure
    return CaseOutcome(task.case_id, first, wall_times, elapsed=time.perf_counter() - start)


def _command_deadline(task: CaseTask) -> Any:
    """The case's timeout as the deadline of a command engine's program (engines.command.deadline)."""
    if task.command is None:
        return contextlib.nullcontext()
    from engines.command import deadline

    return deadline(max(task.timeout - COMMAND_MARGIN, 0.5 * task.timeout))


#: Engine variants this process has run once (see :func:`warm_up`).
_WARM: set[str] = set()


def warm_up(task: CaseTask) -> None:
    """Run the case's engine variant for two steps in this (host) process, once per variant.

    One-off costs (``ours``' numba kernels load from the on-disk cache in
    ~0.5 s; MuJoCo and PyBullet initialize their libraries) then stay out of
    the case's stepping time. Errors are ignored here: the case reports them.
    """
    if task.engine_id in _WARM or task.command is not None:  # a program starts afresh in every run
        return
    _WARM.add(task.engine_id)
    try:
        scene = task.scene.with_duration(min(task.scene.duration, 2 * task.dt))
        _engine_for(task).simulate(scene, task.dt, variant=task.variant, options=task.options)
    except Exception:
        pass


def _failure(task: CaseTask, exc: BaseException) -> CaseOutcome:
    frame = traceback.extract_tb(exc.__traceback__)[-1:] if exc.__traceback__ else []
    where = f" (at {frame[0].filename.rsplit('/', 1)[-1]}:{frame[0].lineno})" if frame else ""
    message = f"{type(exc).__name__}: {exc}".splitlines()[0] + where
    return CaseOutcome(task.case_id, None, status="failed", message=message)


def _host_loop(requests: Any, replies: Any, *worker_ends: Any) -> None:
    """The case host: run each task received until the worker closes the pipe (or dies).

    The fork copied the worker's ends of both pipes into this process; they are
    closed first, or the host itself would hold the request pipe's write end open
    and never see EOF when its worker is killed (an orphan blocked forever).
    """
    for end in worker_ends:
        end.close()
    while True:
        try:
            task = requests.recv()
        except (EOFError, OSError):
            return
        try:
            warm_up(task)
            outcome = simulate(task)
        except BaseException as exc:  # anything the engine throws is this case's result
            outcome = _failure(task, exc)
        try:
            replies.send(outcome)
        except Exception as exc:  # an unpicklable trajectory must still give an answer
            replies.send(_failure(task, exc))


class _Host:
    """A case host process and the worker's ends of its two pipes."""

    def __init__(self) -> None:
        context = multiprocessing.get_context("fork")
        self.requests, child_requests = context.Pipe(duplex=False)[::-1]
        child_replies, self.replies = context.Pipe(duplex=False)[::-1]
        # daemon: it is killed when the worker exits, rather than waited for.
        self.process = context.Process(target=_host_loop, args=(child_requests, child_replies, self.requests, self.replies),
                                       daemon=True, name="xval-case-host")
        self.process.start()
        child_requests.close()
        child_replies.close()  # so a host that dies closes the pipe and recv() sees EOF

    def close(self, kill: bool = False) -> None:
        if kill:
            self.process.kill()
        self.requests.close()
        self.replies.close()
        self.process.join(timeout=10)


_local = threading.local()  # one host per worker thread, so threads never share a pipe


def _signal_name(exitcode: int | None) -> str:
    if exitcode is None:
        return "an unknown cause"
    if exitcode < 0:
        try:
            return f"signal {signal.Signals(-exitcode).name}"
        except ValueError:
            return f"signal {-exitcode}"
    return f"exit code {exitcode}"


def execute(task: CaseTask) -> CaseOutcome:
    """Run ``task`` in this thread's case host (unless ``task.isolate`` is False); never raises for the engine's sake."""
    start = time.perf_counter()
    if not task.isolate:
        try:
            return simulate(task)
        except Exception as exc:
            outcome = _failure(task, exc)
            outcome.elapsed = time.perf_counter() - start
            return outcome
    host: _Host | None = getattr(_local, "host", None)
    if host is None or not host.process.is_alive():
        host = _local.host = _Host()
    try:
        host.requests.send(task)
    except OSError:  # the host died after its last answer: start another
        host.close()
        host = _local.host = _Host()
        host.requests.send(task)
    if not host.replies.poll(task.timeout):
        host.close(kill=True)
        _local.host = None
        return CaseOutcome(
            task.case_id,
            None,
            status="timeout",
            message=f"ran past the timeout of {task.timeout:g} s and was killed; raise --timeout if it is only slow",
            elapsed=time.perf_counter() - start,
        )
    try:
        outcome: CaseOutcome = host.replies.recv()
    except (EOFError, OSError):
        host.close()
        _local.host = None
        return CaseOutcome(
            task.case_id,
            None,
            status="failed",
            message=f"the engine's process died ({_signal_name(host.process.exitcode)}) before returning a result",
            elapsed=time.perf_counter() - start,
        )
    outcome.elapsed = time.perf_counter() - start
    return outcome
