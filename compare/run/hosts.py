"""Case hosts driven straight from the process that runs the suite: how a local run isolates its cases.

A local, isolated run (``xval run``, no cluster) forks ``jobs`` case hosts
(:mod:`compare.run.isolation`) from the ``xval`` process itself and drives them
from the thread that runs the suite: it sends tasks to the hosts, waits on
every busy host's answer pipe at once (``multiprocessing.connection.wait``)
until the first answer or the nearest deadline, and turns each answer, death
or timeout into its future's result exactly as
:func:`~compare.run.isolation.execute` does in an executor's worker thread.

Details: docs/running.md, "Module notes", ``compare/run/hosts.py``.
"""

from __future__ import annotations

import concurrent.futures as cf
import time
from collections import deque
from dataclasses import dataclass, field
from multiprocessing.connection import wait as wait_for_pipes
from multiprocessing.reduction import ForkingPickler
from typing import Any, Iterable

from compare.run.isolation import CaseTask, ReferenceTask, CaseHost, died, reference_answer, send, timed_out


#: Bytes of a pickled task sent to a host still busy with another: the least a Linux pipe holds (one
#: page; pipes past the user's pipe-user-pages-soft get one), so the write never waits for the host.
#: A default-suite case is about 1 KB; a bigger task (a long chain's scene) waits until its host is idle.
PIPELINED_BYTES = 4096


@dataclass
class _Job:
    """A task, its future, and when its host began it (time.perf_counter(), s; 0 until then)."""

    task: CaseTask | ReferenceTask
    future: cf.Future
    started: float = 0.0
    _pickled: memoryview | None = None

    @property
    def pickled(self) -> memoryview:
        """The task as it travels through a pipe (pickled once)."""
        if self._pickled is None:
            self._pickled = ForkingPickler.dumps(self.task)
        return self._pickled

    @property
    def deadline(self) -> float:
        return self.started + self.task.timeout


@dataclass
class _Slot:
    """A case host (None before its first task, or once it ended) and the jobs sent to it, oldest first:
    the first runs, the others wait in its pipe."""

    host: CaseHost | None = None
    jobs: deque[_Job] = field(default_factory=deque)


class HostPool:
    """``size`` case hosts, each running one task at a time, fed from a queue; driven by :meth:`wait`.

    ``submit`` only queues a task; tasks are sent and answers read while some
    thread is in :meth:`wait` (the runner's loop), so everything here runs in
    that one thread and no lock is needed. ``depth``: tasks a host is sent at
    most (the one it runs and those waiting behind it).
    """

    #: The runner made it (it may kill its hosts, and sizes its window by them).
    owned = True

    def __init__(self, size: int, depth: int = 2) -> None:
        if size < 1 or depth < 1:
            raise ValueError(f"a host pool needs at least one host and a depth of 1, not {size} and {depth}")
        self.depth = depth
        self.slots = [_Slot(CaseHost()) for _ in range(size)]
        self.queue: deque[_Job] = deque()

    @property
    def hosts(self) -> list[CaseHost]:
        """The hosts alive now (or not yet seen to have died)."""
        return [slot.host for slot in self.slots if slot.host is not None]

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
                self._send_queued()  # so the hosts carry on while the caller handles what is done
                return done
            self._send_queued()
            busy = {slot.host.replies: slot for slot in self.slots if slot.jobs}
            if not busy:
                raise RuntimeError("waiting on futures this host pool does not run")
            nearest = min(slot.jobs[0].deadline for slot in busy.values())
            for pipe in wait_for_pipes(list(busy), timeout=max(0.0, nearest - time.perf_counter())):
                self._answer(busy[pipe])
            now = time.perf_counter()
            for slot in busy.values():
                if slot.jobs and slot.host is not None and now >= slot.jobs[0].deadline and not slot.host.replies.poll():
                    self._kill(slot)

    def shutdown(self, kill: bool = False) -> None:
        """Close every host (``kill``: SIGKILL each busy host's process group first, not waiting for its
        task); tasks not finished are cancelled."""
        for slot in self.slots:
            if slot.host is not None:
                slot.host.close(kill=kill and bool(slot.jobs))
            for job in slot.jobs:
                job.future.cancel()
        for job in self.queue:
            job.future.cancel()
        self.queue.clear()
        self.slots.clear()

    def _send_queued(self) -> None:
        # Breadth first: every host gets a task to run before any gets one to wait behind it.
        for place in range(self.depth):
            for slot in self.slots:
                if not self.queue or len(slot.jobs) != place:
                    continue
                if place > 0 and len(self.queue[0].pickled) > PIPELINED_BYTES:
                    # It waits for an idle host (docs/running.md, "Module notes"), and the tasks behind it too.
                    return
                job = self.queue.popleft()
                if place == 0:
                    slot.host = send(slot.host, job.task)  # a new host when it has none, or it died
                    job.started = time.perf_counter()
                else:
                    try:
                        slot.host.requests.send_bytes(job.pickled)
                    except OSError:  # the host is gone: the answer it owes says how; this task waits
                        self.queue.appendleft(job)
                        continue
                slot.jobs.append(job)

    def _ended(self, slot: _Slot) -> None:
        """The slot's host is gone: the tasks that waited behind its last one go back to the queue, first."""
        slot.host = None
        while slot.jobs:
            self.queue.appendleft(slot.jobs.pop())

    def _answer(self, slot: _Slot) -> None:
        job = slot.jobs.popleft()
        try:
            answer, exiting = slot.host.replies.recv()
        except (EOFError, OSError):
            slot.host.close()
            outcome = died(job.task, slot.host, job.started)
            self._ended(slot)
            self._finish(job, outcome)
            return
        if exiting:  # it ran out of memory and exits: what waited behind goes to a new host
            slot.host.close()
            self._ended(slot)
        elif slot.jobs:
            slot.jobs[0].started = time.perf_counter()  # the host took the next task as it answered
        self._finish(job, answer)

    def _kill(self, slot: _Slot) -> None:
        job, host = slot.jobs.popleft(), slot.host
        host.close(kill=True)
        self._ended(slot)
        self._finish(job, timed_out(job.task, job.started, host))

    @staticmethod
    def _finish(job: _Job, answer: Any) -> None:
        if isinstance(job.task, ReferenceTask):
            try:
                job.future.set_result(reference_answer(job.task, answer))
            except Exception as exc:  # ReferenceFailed: the runner keeps it as the scene's reference
                job.future.set_exception(exc)
            return
        if not answer.elapsed:  # the engine raised before simulate timed the case: time it from here
            answer.elapsed = time.perf_counter() - job.started
        # Otherwise the host's own measure: with a task waiting behind, the time between two answers
        # seen here would also count what this process did between them.
        job.future.set_result(answer)
