"""Running one case so that whatever the engine does (raise, hang, segfault) only that case pays.

Each case runs in a *case host*, a child forked from the driving process that runs cases one after
another and answers on a pipe; the driver waits at most ``timeout`` s. An exception is ``failed``,
a dead host is ``failed`` with its exit code or signal, no answer in time kills the host and is
``timeout``; the next case gets a new host. Nothing xval starts outlives it (process groups,
PR_SET_PDEATHSIG, a reaper), and ``RLIMIT_AS`` bounds each task's memory.

Details: docs/running.md, "Module notes", ``compare/run/isolation.py``.
"""

from __future__ import annotations

import contextlib
import ctypes
import faulthandler
import multiprocessing
import os
import signal
import sys
import threading
import time
import traceback
from dataclasses import dataclass, replace
from typing import Any, BinaryIO, Mapping

from engines.adapter import Engine, scheduled_times
from engines.scene.scene import SceneLike
from engines.scene.trajectory import Status, Trajectory
from engines.stdio import EngineOutput, capture_output, left_in, line_buffered, output_file

from compare.results.measure import CaseOutcome


@dataclass(frozen=True)
class CaseTask:
    """Everything a worker needs to run one case (picklable).

    engine_id : ``name/variant`` or ``module:ATTRIBUTE/variant``, loaded in the process that runs the case.
    dt, sample_interval, timeout : s. repeats : runs whose stepping times are kept.
    """

    case_id: str
    engine_id: str
    variant: str | None
    options: Mapping[str, Any]
    scene: SceneLike
    dt: float
    sample_interval: float
    repeats: int = 1
    timeout: float = 120.0
    isolate: bool = True
    memory_limit: int | None = None
    #: An outside program's spec (engines.external.command.spec_of), so any worker, here or on another machine, can run it.
    command: Mapping[str, Any] | None = None
    #: [gradients] wrt: after the runs, the case's gradient metrics (compare.gradients.measure.gradient_metrics).
    gradient_wrt: tuple[str, ...] = ()


@dataclass(frozen=True)
class ReferenceTask:
    """The reference solve of one scene, run in a case host like a case (picklable).

    rtol, atol : DOP853's tolerances. timeout : s. memory_limit : bytes of address space, or None.
    sample_dts, sample_interval : s; the run's cases of this scene are sampled at
        engines.adapter.scheduled_times(duration, dt, sample_interval) for each of these dts: the host
        evaluates the solution there (and keeps the samples with it), so the parent finds them
        in ReferenceSolution.samples. (The dts, not the times: a task of a few KB can be sent to
        a host still busy with the one before it, compare.run.hosts.PIPELINED_BYTES.)
    """

    scene_id: str
    scene: SceneLike
    rtol: float
    atol: float
    timeout: float = 120.0
    isolate: bool = True
    memory_limit: int | None = None
    sample_dts: tuple[float, ...] = ()
    sample_interval: float | None = None

    @property
    def name(self) -> str:
        """The scene's name (what a Dask dashboard shows beside ``solve_reference``)."""
        return self.scene.name

    @property
    def case_id(self) -> str:
        return f"reference of scene {self.scene_id}"


class ReferenceFailed(RuntimeError):
    """The reference of a scene could not be solved (raised, timed out, died); the message says which."""


#: Fewest repeats for which the calibration kernel runs: the timing gate judges only cases timed at
#: least twice (compare.gate.gate.MIN_TIMING_REPEATS), so a single repeat's ~3 ms calibration would be
#: spent for nothing (about a tenth of the harness's CPU on the default suite, which runs once).
MIN_CALIBRATED_REPEATS = 2


def calibration_cpu_time() -> float:
    """s of this thread's CPU time for a fixed small kernel (~3 ms: 800 products of 24x24 matrices in a
    Python loop, so both the interpreter and compiled code are in it).

    Timed beside each repeat of a case, it measures how fast this CPU is
    *right now*: a core shared with another VM's thread, a lower clock or a
    cache shared with a busy neighbour slow the kernel and the engine alike,
    so the timing gate divides one by the other (compare/gate/gate.py).
    """
    import numpy as np

    rng = np.random.default_rng(0)
    a, b = rng.standard_normal((24, 24)), rng.standard_normal((24, 24)) / 5
    started = time.thread_time()
    for _ in range(800):
        a = a @ b
        a /= np.abs(a).max()
    return time.thread_time() - started


def _engine_for(task: CaseTask) -> Engine:
    from engines.registry import load_engine  # here, not at import: loaded in the process that runs the case

    if task.command is not None:
        from engines.external.command import adopt

        return adopt(task.command)
    return load_engine(task.engine_id)[0]


#: s a command engine's deadline leaves before the case's timeout, to kill its program's process
#: group and answer ``timeout`` before the driver kills the host (which would orphan the program).
COMMAND_MARGIN = 0.5


def simulate(task: CaseTask) -> CaseOutcome:
    """Run the case in this process: the first run gives the trajectory, every run a stepping time."""
    start = time.perf_counter()
    engine = _engine_for(task)
    first: Trajectory | None = None
    wall_times: list[float] = []
    cpu_times: list[float] = []
    calibrations: list[float] = []
    with _command_deadline(task):
        for _ in range(task.repeats):
            if task.repeats >= MIN_CALIBRATED_REPEATS:
                calibrations.append(calibration_cpu_time())
            trajectory = engine.simulate(
                task.scene, task.dt, variant=task.variant, options=task.options, sample_interval=task.sample_interval
            )
            wall_times.append(trajectory.info.wall_time)
            cpu_times.append(trajectory.info.cpu_time)
            if trajectory.info.status is Status.FAILED and trajectory.info.message.startswith("MemoryError"):
                trajectory = _out_of_memory(task, trajectory)
            first = first or trajectory
            if trajectory.info.status is not Status.OK:
                break  # repeating a failed or unstable run would only time the failure
    gradients: dict[str, Any] = {}
    gradient_series: dict[str, Any] = {}
    if task.gradient_wrt and first is not None and first.info.status is Status.OK:
        from compare.gradients.measure import gradient_measurement

        gradients, gradient_series = gradient_measurement(engine, task.variant, task.options, task.scene, task.dt,
                                                          task.gradient_wrt)
    return CaseOutcome(task.case_id, first, wall_times, elapsed=time.perf_counter() - start, cpu_times=cpu_times,
                       calibrations=calibrations[:len(cpu_times)], gradients=gradients,
                       gradient_series=gradient_series)


def _command_deadline(task: CaseTask) -> Any:
    """The case's timeout as the deadline of a command engine's program (engines.external.command.deadline)."""
    if task.command is None:
        return contextlib.nullcontext()
    from engines.external.command import deadline

    return deadline(max(task.timeout - COMMAND_MARGIN, 0.5 * task.timeout))


#: Engine variants this process has run once (see :func:`warm_up`).
_WARM: set[str] = set()


def warm_up(task: CaseTask) -> None:
    """Run the case's engine variant for two steps in this (host) process, once per variant.

    One-off costs (``ours``' numba kernels load from the on-disk cache in
    ~0.5 s; MuJoCo and PyBullet initialize their libraries) then stay out of
    the case's stepping time. Errors are ignored here: the case reports them.
    """
    if task.engine_id in _WARM:
        return
    _WARM.add(task.engine_id)
    try:
        engine = _engine_for(task)
        if not engine.needs_warm_up:  # a program started afresh in every run
            return
        scene = task.scene.with_duration(min(task.scene.duration, 2 * task.dt))
        engine.simulate(scene, task.dt, variant=task.variant, options=task.options)
    except Exception:
        pass


#: Default address space a case may add to its host's, bytes (``--memory-limit``).
DEFAULT_MEMORY_LIMIT = 4 * 2**30

_PR_SET_PDEATHSIG = 1


def die_with_parent(sig: int = signal.SIGKILL) -> None:
    """Ask the kernel to send ``sig`` to this process when its parent dies (Linux; a no-op elsewhere).

    Used as the pool workers' initializer and by every case host, so a
    ``kill -9`` of ``xval`` takes its hosts and workers (and theirs) with it.
    The check of the parent after the call closes the window in which the
    parent died before the request was made.
    """
    if not sys.platform.startswith("linux"):
        return
    parent = os.getppid()
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, int(sig), 0, 0, 0)
    except (OSError, AttributeError):  # no prctl here: the pipes still end orphaned hosts
        return
    if os.getppid() != parent:
        os._exit(1)


def _kill_own_group(signum: int, frame: Any) -> None:
    """The host's SIGTERM handler: SIGKILL the process groups of any outside program the engine runs
    (engines.external.command starts each in a session of its own), then the host's own group (the host and
    any child of the engine)."""
    command = sys.modules.get("engines.external.command")
    for group in list(getattr(command, "LIVE_GROUPS", ())):
        try:
            os.killpg(group, signal.SIGKILL)
        except OSError:
            pass
    os.killpg(os.getpgrp(), signal.SIGKILL)


def _become_host() -> None:
    """Lead a process group of our own; die with the process that forked us, and take the group down.

    The kernel SIGKILLs the host when its driver dies (SIGKILL, not SIGTERM: a host deep in a compiled
    loop — a numba kernel, a C++ engine — runs no Python signal handler until the loop returns, which
    left hosts running for minutes after a ``kill -9`` of xval). A SIGKILLed host cannot clean up, so a
    reaper does it (:func:`_start_reaper`). SIGTERM (a user's ``kill``) still takes the group down at once.
    """
    try:
        os.setpgid(0, 0)
    except OSError:
        pass
    signal.signal(signal.SIGTERM, _kill_own_group)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the xval process's to handle
    _start_reaper()
    die_with_parent(signal.SIGKILL)


class _ReportedGroups(set):
    """engines.external.command.LIVE_GROUPS in a host: each outside program's process group, also told to the reaper."""

    def __init__(self, fd: int, groups: Any = ()) -> None:
        super().__init__(groups)
        self.fd = fd

    def add(self, group: int) -> None:
        super().add(group)
        os.write(self.fd, b"+%d\n" % group)

    def discard(self, group: object) -> None:
        super().discard(group)
        os.write(self.fd, b"-%d\n" % int(group))  # type: ignore[call-overload]  # a group id: an int


def _start_reaper() -> None:
    """Fork the host's reaper: a small process, in the host's group, that waits on a pipe only the host
    holds. When the host dies (EOF), however it died, the reaper SIGKILLs the process groups of the
    outside programs the host had running (each in a session of its own, engines.external.command; the host
    reports them on the pipe), then the host's group — the engine's own children, and itself."""
    from engines.external import command  # small, no engine library: the reaper needs its LIVE_GROUPS to report to

    read_end, write_end = os.pipe()
    pid = os.fork()
    if pid == 0:  # the reaper: touches no Python object of the host beyond these lines
        try:
            os.close(write_end)
            os.closerange(3, read_end)  # the driver's pipes above all: their EOF tells the driver a host died
            os.closerange(read_end + 1, 1 << 16)
            groups: set[int] = set()
            pending = b""
            while chunk := os.read(read_end, 4096):
                pending += chunk
                *lines, pending = pending.split(b"\n")
                for line in lines:
                    (groups.add if line[:1] == b"+" else groups.discard)(int(line[1:]))
            for group in groups:
                with contextlib.suppress(OSError):
                    os.killpg(group, signal.SIGKILL)
            os.killpg(os.getpgrp(), signal.SIGKILL)
        finally:
            os._exit(0)
    os.close(read_end)
    command.LIVE_GROUPS = _ReportedGroups(write_end, command.LIVE_GROUPS)


def _address_space() -> int:
    """Bytes of address space this process maps now (the size field of /proc/self/statm; 0 where /proc
    is missing). Read before every task, so the one-line file rather than /proc/self/status."""
    try:
        with open("/proc/self/statm", "rb") as statm:
            return int(statm.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        return 0


def _limit_memory(limit: int | None) -> None:
    """Let this process map at most ``limit`` bytes more than it does now (soft RLIMIT_AS; None: no limit).

    Counted from the host's size as the task starts (numba, MuJoCo and
    PyBullet loaded, and more on a machine where libraries reserve per-core
    thread arenas), so one ``--memory-limit`` means the same on every
    machine, and what the host keeps between cases (an engine's cached models,
    kernels loaded for an earlier scene) is not counted against a later case.
    """
    try:
        import resource
    except ImportError:  # not POSIX
        return
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    want = hard if limit is None else _address_space() + limit
    if hard != resource.RLIM_INFINITY:
        want = min(want, hard)
    if want != soft:
        resource.setrlimit(resource.RLIMIT_AS, (want, hard))


def format_bytes(n: int) -> str:
    """``4294967296`` -> ``4 GiB``."""
    for unit, size in (("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if n >= size:
            return f"{n / size:g} {unit}"
    return f"{n} B"


def _memory_message(task: Any, message: str) -> str:
    return (f"ran out of memory past the memory limit of {format_bytes(task.memory_limit)} "
            f"({message}); raise --memory-limit if the case needs more")


def _out_of_memory(task: CaseTask, trajectory: Trajectory) -> Trajectory:
    """The engine's ``failed`` trajectory with the memory limit named in its message (Engine.simulate
    caught the MemoryError); the host then exits, since a process that hit its limit may be in any state."""
    if task.memory_limit is None:
        return trajectory
    _HIT_LIMIT.set()
    info = replace(trajectory.info, message=_memory_message(task, trajectory.info.message))
    return replace(trajectory, info=info)


#: Set when a task in this host ran out of memory: the host answers, then exits.
_HIT_LIMIT = threading.Event()


def _failure(task: Any, exc: BaseException) -> CaseOutcome:
    frame = traceback.extract_tb(exc.__traceback__)[-1:] if exc.__traceback__ else []
    where = f" (at {frame[0].filename.rsplit('/', 1)[-1]}:{frame[0].lineno})" if frame else ""
    message = f"{type(exc).__name__}: {exc}".splitlines()[0] + where
    if isinstance(exc, MemoryError) and task.memory_limit is not None:
        message = _memory_message(task, message)
    return CaseOutcome(task.case_id, None, status=Status.FAILED, message=message)


def _run_in_host(task: Any) -> Any:
    """What the host does with one task: a case's CaseOutcome, or a reference's solution."""
    if isinstance(task, ReferenceTask):
        from engines.reference.reference import solve_and_bound_kept

        times = [scheduled_times(task.scene.duration, dt, task.sample_interval) for dt in task.sample_dts]
        return solve_and_bound_kept(task.scene, rtol=task.rtol, atol=task.atol, sample_times=times)
    warm_up(task)
    return simulate(task)


#: The driver's ends of the pipes of every host this process runs, and their output files. A fork copies
#: them all into the new host, which closes them first: a host holding the write end of its own request
#: pipe, or a sibling's, would keep that host from seeing EOF when its driver closes the pipe or is killed
#: (an orphan blocked in recv() forever, or a run that waits for a host that never ends); a sibling's
#: output file would stay on disk (unnamed, but full) until every host that holds it ends.
_DRIVER_ENDS: set[Any] = set()
#: Held from a host's pipes' creation to its fork, so a host forked by another thread at the same time
#: never inherits ends it does not know of.
_FORKING = threading.Lock()


def _host_loop(requests: Any, replies: Any, output: BinaryIO) -> None:
    """The case host: run each task received until its driver closes the pipe (or dies).

    output : the file (engines.stdio.output_file) each task's printing goes to, which its driver reads
        when the host dies mid-task; emptied once the task's answer has its summary.
    """
    for end in list(_DRIVER_ENDS):
        if end is not output:
            end.close()
    _DRIVER_ENDS.clear()
    _become_host()
    line_buffered()  # a host that dies keeps its last lines in ``output``, not in a buffer that dies with it
    if faulthandler.is_enabled():  # its dump goes where it was pointed (pytest: a copy of stderr): to the case's
        faulthandler.enable(file=2)
    while True:
        try:
            task = requests.recv()
        except (EOFError, OSError):
            return
        out_of_memory = False
        # What the engine prints is this case's, kept with its answer: never the terminal's (docs/architecture.md).
        with capture_output(output) as captured:
            try:
                _limit_memory(task.memory_limit)
                outcome = _run_in_host(task)
            except BaseException as exc:  # anything the engine throws is this case's result
                out_of_memory = isinstance(exc, MemoryError)
                outcome = _failure(task, exc)
            finally:
                _limit_memory(None)
        if isinstance(outcome, CaseOutcome):
            outcome.output = captured.output
        # A process that hit its limit may be in any state: it says so with its answer and exits, so
        # the driver starts a new host for the next case rather than send it to one on its way out.
        exiting = out_of_memory or _HIT_LIMIT.is_set()
        try:
            replies.send((outcome, exiting))
        except Exception as exc:  # an unpicklable trajectory must still give an answer
            replies.send((_failure(task, exc), exiting))
        if exiting:
            return


class CaseHost:
    """A case host process, its driver's ends of its two pipes (the driver: the process that forked it) and the
    file its tasks print into (engines.stdio.output_file, held by both).

    left : once closed, what the task it was running when it ended had printed (empty after an answer).
    """

    left: EngineOutput = EngineOutput()

    def __init__(self) -> None:
        self.owner = os.getpid()  # a forked child inherits this object (thread-locals survive fork) but not the host
        context = multiprocessing.get_context("fork")
        with _FORKING:
            self.requests, child_requests = context.Pipe(duplex=False)[::-1]
            child_replies, self.replies = context.Pipe(duplex=False)[::-1]
            self.output = output_file()
            _DRIVER_ENDS.update((self.requests, self.replies, self.output))
            # daemon: it is killed when its driver exits, rather than waited for.
            self.process = context.Process(target=_host_loop, args=(child_requests, child_replies, self.output),
                                           daemon=True, name="xval-case-host")
            self.process.start()
        try:
            os.setpgid(self.process.pid, self.process.pid)  # also done by the host: whichever runs first
        except OSError:
            pass
        child_requests.close()
        child_replies.close()  # so a host that dies closes the pipe and recv() sees EOF

    def close(self, kill: bool = False) -> None:
        if kill:  # the host's whole group: the engine's own children too
            try:
                os.killpg(self.process.pid, signal.SIGKILL)
            except OSError:
                self.process.kill()
        with _FORKING:  # listed until closed: a host forked meanwhile by another thread closes its copies
            _DRIVER_ENDS.difference_update((self.requests, self.replies, self.output))
            self.requests.close()
            self.replies.close()
        self.process.join(timeout=10)
        if not self.output.closed:  # a second close finds it read already
            with self.output:
                # A host that answered left it empty; one killed or dead mid-task left what that task printed.
                self.left = left_in(self.output)


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


def execute_reference(task: ReferenceTask) -> Any:
    """The scene's reference solution, solved in this thread's case host under ``task.timeout``.

    Raises ReferenceFailed saying why (the solver raised, ran past the
    timeout, died or ran out of memory); the runner records it in each case
    of the scene, whose position metrics are then null.
    """
    if not task.isolate:
        return _run_in_host(task)  # what a host does with it, here
    return reference_answer(task, _ask_host(task))


def reference_answer(task: ReferenceTask, answer: Any) -> Any:
    """The host's answer to a reference task: the solution, or ReferenceFailed when the answer is the
    ``failed`` / ``timeout`` CaseOutcome of a solve that raised, ran past the timeout or died."""
    if isinstance(answer, CaseOutcome):
        raise ReferenceFailed(f"the reference of scene {task.scene_id!r} {answer.message}")
    return answer


def execute(task: CaseTask) -> CaseOutcome:
    """Run ``task`` in this thread's case host (unless ``task.isolate`` is False); never raises for the engine's sake."""
    start = time.perf_counter()
    if not task.isolate:
        with capture_output() as captured:
            try:
                warm_up(task)  # as a case host does: the variant's one-off costs stay out of its first case's stepping
                outcome = simulate(task)
            except Exception as exc:
                outcome = _failure(task, exc)
                outcome.elapsed = time.perf_counter() - start
        outcome.output = captured.output
        return outcome
    outcome = _ask_host(task)
    if not outcome.elapsed:  # as HostPool: the host's own measure, else (no answer) the time waited here
        outcome.elapsed = time.perf_counter() - start
    return outcome


def _ask_host(task: Any) -> Any:
    """Send ``task`` to this thread's host and wait at most ``task.timeout`` s for its answer.

    Returns the host's answer, or a ``timeout`` / ``failed`` CaseOutcome when
    it gave none (killed at the timeout, or died).
    """
    start = time.perf_counter()
    host = _local.host = send(getattr(_local, "host", None), task)
    if not host.replies.poll(task.timeout):
        host.close(kill=True)
        _local.host = None
        return timed_out(task, start, host)
    try:
        answer, exiting = host.replies.recv()
    except (EOFError, OSError):
        host.close()
        _local.host = None
        return died(task, host, start)
    if exiting:
        host.close()
        _local.host = None
    return answer


def send(host: CaseHost | None, task: Any) -> CaseHost:
    """Send ``task`` to ``host``, or to a new host when it is None, dead, or another process's (a forked
    child inherits its parent's objects, not its hosts); returns the host that has the task."""
    if host is not None and host.owner == os.getpid() and not host.process.is_alive():
        host.close()  # our dead host: its pipe ends are ours to close (_DRIVER_ENDS holds them till then)
        host = None
    if host is None or host.owner != os.getpid():
        host = CaseHost()
    try:
        host.requests.send(task)
    except OSError:  # the host died after its last answer: start another
        host.close()
        host = CaseHost()
        host.requests.send(task)
    return host


def timed_out(task: Any, start: float, host: CaseHost | None = None) -> CaseOutcome:
    """The ``timeout`` outcome of a task whose host gave no answer within ``task.timeout`` (and was killed);
    a case's message says how to give it longer; a reference's, quoted in its scene's case records, does not.
    start : time.perf_counter() when its host began it. host : the killed host, closed: what the task
    printed before it was killed is kept as the outcome's output."""
    hint = "" if isinstance(task, ReferenceTask) else "; raise --timeout if it is only slow"
    return CaseOutcome(task.case_id, None, status=Status.TIMEOUT, elapsed=time.perf_counter() - start,
                       message=f"ran past the timeout of {task.timeout:g} s and was killed{hint}",
                       output=host.left if host is not None else EngineOutput())


def died(task: Any, host: CaseHost, start: float) -> CaseOutcome:
    """The ``failed`` outcome of a task whose host died before answering (``host`` closed, so its exit
    code is known, and what the task printed before it died). start : time.perf_counter() when its host began it."""
    return CaseOutcome(task.case_id, None, status=Status.FAILED, elapsed=time.perf_counter() - start,
                       message=f"the engine's process died ({_signal_name(host.process.exitcode)}) before "
                               f"returning a result", output=host.left)
