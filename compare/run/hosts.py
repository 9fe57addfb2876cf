"""Case hosts driven straight from the process that runs the suite: how a local run isolates its cases.

A local, isolated run (``xval run``, no cluster) forks ``jobs`` case hosts
(:mod:`compare.run.isolation`) from the ``xval`` process itself and drives them
from the thread that runs the suite: it sends a task to an idle host, waits on
every busy host's answer pipe at once (``multiprocessing.connection.wait``)
until the first answer or the nearest deadline, and turns each answer, death
or timeout into its future's result exactly as
:func:`~compare.run.isolation.execute` does in an executor's worker thread.

Why not a ProcessPoolExecutor whose workers each fork a host: its workers
never run engine code, so all they did was pass each task and each trajectory
on (a trajectory pickled three times, not once, and a process and two feeder
threads kept busy doing it); ``bench/bench_harness.py`` measures what a run
costs around the physics. A host's death here is its case's failure, never a
broken pool.

Forks happen only in the driving thread, at :class:`HostPool` construction
(before the progress bar starts its thread) and to replace a host that died,
timed out or ran out of memory. Each host asks for SIGTERM when the ``xval``
process dies (``die_with_parent``), so a ``kill -9`` of xval still ends them.
"""

from __future__ import annotations

import concurrent.futures as cf
import time
from collections import deque
from dataclasses import dataclass
from multiprocessing.connection import wait as wait_for_pipes
from typing import Any, Iterable

from compare.run.isolation import CaseTask, ReferenceTask, CaseHost, died, reference_answer, send, timed_out


@dataclass
class _Job:
    """A task, its future, and when it was sent (time.perf_counter(), s); deadline = sent + task.timeout."""

    task: CaseTask | ReferenceTask
    future: cf.Future
    sent: float = 0.0

    @property
    def deadline(self) -> float:
        return self.sent + self.task.timeout


class HostPool:
    """``size`` case hosts, each running one task at a time, fed from a queue; driven by :meth:`wait`.

    ``submit`` only queues a task; tasks are sent and answers read while some
    thread is in :meth:`wait` (the runner's loop), so everything here runs in
    that one thread and no lock is needed.
    """

    def __init__(self, size: int) -> None:
        if size < 1:
            raise ValueError(f"a host pool needs at least one host, not {size}")
        self.idle: list[CaseHost | None] = [CaseHost() for _ in range(size)]  # None: replace before use
        self.busy: dict[Any, tuple[CaseHost, _Job]] = {}  # by the host's answer pipe
        self.queue: deque[_Job] = deque()

    def submit(self, task: CaseTask | ReferenceTask) -> cf.Future:
        """A future of what :func:`~compare.run.isolation.execute` (a case: its CaseOutcome) or
        :func:`~compare.run.isolation.execute_reference` (a reference: its solution, or ReferenceFailed)
        would give for ``task``."""
        job = _Job(task, cf.Future())
        self.queue.append(job)
        return job.future

    def wait(self, futures: Iterable[cf.Future]) -> set[cf.Future]:
        """Run tasks until at least one of ``futures`` is done; returns those that are."""
        futures = list(futures)
        while True:
            done = {f for f in futures if f.done()}
            if done:
                return done
            if not (self.queue or self.busy):
                raise RuntimeError("waiting on futures this host pool does not run")
            self._send_queued()
            now = time.perf_counter()
            nearest = min(job.deadline for _, job in self.busy.values())
            for pipe in wait_for_pipes(list(self.busy), timeout=max(0.0, nearest - now)):
                self._answer(pipe)
            now = time.perf_counter()
            for pipe, (_, job) in list(self.busy.items()):
                if now >= job.deadline and not pipe.poll():
                    self._kill(pipe)

    def shutdown(self, kill: bool = False) -> None:
        """Close every host (``kill``: SIGKILL each busy host's process group first, not waiting for its
        task); queued tasks are cancelled."""
        for job in self.queue:
            job.future.cancel()
        self.queue.clear()
        for host, job in self.busy.values():
            host.close(kill=kill)
            job.future.cancel()
        self.busy.clear()
        for host in self.idle:
            if host is not None:
                host.close()
        self.idle.clear()

    def _send_queued(self) -> None:
        while self.queue and self.idle:
            job = self.queue.popleft()
            job.sent = time.perf_counter()
            host = send(self.idle.pop(), job.task)
            self.busy[host.replies] = (host, job)

    def _answer(self, pipe: Any) -> None:
        host, job = self.busy.pop(pipe)
        try:
            answer, exiting = pipe.recv()
        except (EOFError, OSError):
            host.close()
            self._finish(job, died(job.task, host, job.sent))
            self.idle.append(None)
            return
        if exiting:  # it ran out of memory: it exits, and the next task gets a new host
            host.close()
        self.idle.append(None if exiting else host)
        self._finish(job, answer)

    def _kill(self, pipe: Any) -> None:
        host, job = self.busy.pop(pipe)
        host.close(kill=True)
        self.idle.append(None)
        self._finish(job, timed_out(job.task, job.sent))

    @staticmethod
    def _finish(job: _Job, answer: Any) -> None:
        if isinstance(job.task, ReferenceTask):
            try:
                job.future.set_result(reference_answer(job.task, answer))
            except Exception as exc:  # ReferenceFailed: the runner keeps it as the scene's reference
                job.future.set_exception(exc)
            return
        answer.elapsed = time.perf_counter() - job.sent
        job.future.set_result(answer)
