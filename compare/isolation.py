"""Running one case so that whatever the engine does (raise, hang, segfault) only that case pays.

:func:`execute` is what the runner submits to its Executor. With
``isolate`` (the default) it forks a child process per case from the worker
that received it, and waits for the child's answer on a pipe at most
``timeout`` seconds:

- the engine raised: the child catches it and answers ``failed``;
- the child died (a segfault, ``os._exit``, SIGKILL): the pipe closes
  without an answer, and the case is ``failed`` with the exit code or signal;
- no answer in time: the child is killed and the case is ``timeout``.

Forking per case (rather than running cases in the pool's workers
directly) is what keeps a ``ProcessPoolExecutor`` usable after a case kills
its process: the worker itself never dies, so the pool never breaks. A fork
copies the worker's already imported engines, so the cost is a few
milliseconds per case. It needs the ``fork`` start method (Linux, macOS);
with ``isolate=False`` the case runs in the worker itself (no timeout, and
a crash breaks the pool, which the runner then rebuilds).
"""

from __future__ import annotations

import multiprocessing
import signal
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
    from compare.suite import load_engine  # here, not at import: workers need not parse suites

    return load_engine(task.engine_id)[0]


def simulate(task: CaseTask) -> CaseOutcome:
    """Run the case in this process: the first run gives the trajectory, every run a stepping time."""
    start = time.perf_counter()
    engine = _engine_for(task)
    first: Trajectory | None = None
    wall_times: list[float] = []
    for _ in range(task.repeats):
        trajectory = engine.simulate(
            task.scene, task.dt, variant=task.variant, options=task.options, sample_interval=task.sample_interval
        )
        wall_times.append(trajectory.info.wall_time)
        first = first or trajectory
        if trajectory.info.status != "ok":
            break  # repeating a failed or unstable run would only time the failure
    return CaseOutcome(task.case_id, first, wall_times, elapsed=time.perf_counter() - start)


#: Built-in engine variants this process has run once (see :func:`warm_up`).
_WARM: set[str] = set()


def warm_up(task: CaseTask) -> None:
    """Run a built-in engine variant for two steps in this (worker) process, once.

    Forked children inherit what the worker has loaded, so one-off costs
    (``ours``' numba kernels load from the on-disk cache in ~0.5 s, MuJoCo
    and PyBullet initialize their libraries) are paid once per worker, not
    once per case. Only built-in engines are warmed: an engine loaded by
    ``module:attribute`` could kill the worker, which is what the per-case
    child is for. Errors here are ignored: the real case reports them.
    """
    if task.engine_id in _WARM or ":" in task.engine_id:
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


def _child(connection: Any, task: CaseTask) -> None:
    try:
        outcome = simulate(task)
    except BaseException as exc:  # anything the engine throws is this case's result
        outcome = _failure(task, exc)
    try:
        connection.send(outcome)
    except Exception as exc:  # an unpicklable trajectory must still give an answer
        connection.send(_failure(task, exc))
    connection.close()


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
    """Run ``task``, isolated in a forked child unless ``task.isolate`` is False; never raises for the engine's sake."""
    start = time.perf_counter()
    if not task.isolate:
        try:
            return simulate(task)
        except Exception as exc:
            outcome = _failure(task, exc)
            outcome.elapsed = time.perf_counter() - start
            return outcome
    warm_up(task)
    context = multiprocessing.get_context("fork")
    reader, writer = context.Pipe(duplex=False)
    child = context.Process(target=_child, args=(writer, task), name=f"xval-case {task.case_id}")
    child.start()
    writer.close()  # so a child that dies closes the pipe and recv() sees EOF
    try:
        outcome: CaseOutcome | None = None
        if reader.poll(task.timeout):
            try:
                outcome = reader.recv()
            except (EOFError, OSError):
                outcome = None
        else:
            child.kill()
            child.join()
            return CaseOutcome(
                task.case_id,
                None,
                status="timeout",
                message=f"ran past the timeout of {task.timeout:g} s and was killed; raise --timeout if it is only slow",
                elapsed=time.perf_counter() - start,
            )
        child.join(timeout=30)
        if child.is_alive():  # answered but will not exit: do not let it linger
            child.kill()
            child.join()
        if outcome is None:
            return CaseOutcome(
                task.case_id,
                None,
                status="failed",
                message=f"the engine's process died ({_signal_name(child.exitcode)}) before returning a result",
                elapsed=time.perf_counter() - start,
            )
        outcome.elapsed = time.perf_counter() - start
        return outcome
    finally:
        reader.close()
        child.close() if child.exitcode is not None else None
