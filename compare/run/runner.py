"""Running a suite: cases through case hosts or a concurrent.futures.Executor, one record written per
finished case.

The runner takes the suite's cases (compare.run.plan), solves each scene's reference once, dispatches
the cases to case hosts (compare.run.isolation) or an executor, and writes each case's record as it
finishes (measured by compare.results.measure), so an interrupted run resumes without redoing finished
cases.

Details: docs/running.md, "Module notes", ``compare/run/runner.py``.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import gc
import multiprocessing
import os
import time
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable


from engines.external.command import spec_of

from compare.run.environment import environment
from compare.run.hosts import HostPool
from compare.run.lock import RunLock
from compare.run import startup
from compare.run.isolation import (DEFAULT_MEMORY_LIMIT, CaseTask, ReferenceTask, die_with_parent, execute,
                                   execute_reference)
from engines.files import remove_stale_temporaries
from compare.results.measure import CaseOutcome, SampledReference, SceneFields, measure
from compare.run.progress import NullProgress, Progress
from compare.results.record import CaseRecord, Status, status_counts
from compare.results.store import ResultsDir
from compare.run.plan import Case, check_sizes, key_of, plan, skip_reason
from compare.run.results import Results
from compare.suite.reader import Suite

#: Runs of a case whose executor breaks under it: once among others, then once alone
#: (the Dask executor's allowed-failures follows this).
MAX_ATTEMPTS = 2
#: Why a case that broke its executor twice (the second time alone) is failed.
LOST_MESSAGE = "a worker process of the executor died while it ran"


class RunStopped(Exception):
    """Raised by an executor's future when the executor can run nothing more (a lost cluster scheduler).

    Unlike a case that failed, it stops the run: cases not yet finished get no
    record (so ``--resume`` runs them later), finished ones stay on disk.
    """


def solve_reference(task: ReferenceTask) -> Any:
    """The reference's (dense solution, ReferenceBound) of ``task.scene``, solved in a case host
    under the case timeout (what an executor's worker runs; module-level so it pickles). Raises ReferenceFailed saying
    why not. The bound (engines.reference.reference.solve_and_bound_kept) is the reference's own error bar and horizon."""
    return execute_reference(task)


@dataclass(frozen=True)
class RunSummary:
    """What a run did: where results are, status counts, cases run now / resumed, wall time (s),
    every case record in ``path`` (an earlier run's, read as the run started, and this run's, kept
    as they were written), for the counts and the tables, and run.json as the run finished it."""

    path: Path
    counts: dict[str, int]
    ran: int
    already_done: int
    wall_time: float
    records: list[CaseRecord]
    header: dict[str, Any]

    def results(self) -> Results:
        """The results directory as :func:`compare.run.results.load_results` would read it back, without
        reading it: the records are those the run holds."""
        return Results(self.path, self.header, self.records)


def default_jobs() -> int:
    """All cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def run_suite(suite: Suite, output: str | Path, **options: Any) -> RunSummary:
    """Run ``suite`` into ``output`` (see :func:`_run_suite` for the options), holding the directory's lock.

    Every case's size (steps, samples) is checked first: an absurd one is a
    UserError before anything is written. A second run of the same directory
    while this one holds it is a UserError naming this one's pid.
    """
    check_sizes(suite)
    with RunLock(output):
        return _run_suite(suite, output, **options)


def _run_suite(
    suite: Suite,
    output: str | Path,
    *,
    jobs: int | None = None,
    executor: cf.Executor | None = None,
    resume: bool = False,
    timeout: float | None = None,
    progress: Progress | None = None,
    isolate: bool = True,
    environment_extra: dict[str, Any] | None = None,
    memory_limit: int | None = DEFAULT_MEMORY_LIMIT,
) -> RunSummary:
    """Run every case of ``suite`` not yet recorded in ``output`` and write one record per case.

    jobs : case hosts run at once (or, not isolated, worker processes of a
        ProcessPoolExecutor); all cores when None; ignored when ``executor``
        is given (any Executor works: a ThreadPoolExecutor, a cluster's; cases
        are still isolated in forked children unless ``isolate`` is False).
    timeout : s per case; the suite's ``timeout`` when None.
    resume : continue the run already in ``output`` (same suite required).
    environment_extra : more entries for run.json's ``environment`` (a
        cluster's address and workers, see :mod:`compare.run.cluster`).
    memory_limit : bytes of address space per case host (None: no limit);
        a case past it is ``failed`` with the reason.
    """
    started = time.perf_counter()
    progress = progress or NullProgress()
    header = {
        "suite": {
            "name": suite.name,
            "description": suite.description,
            "path": suite.path,
            "fingerprint": suite.fingerprint(),
        },
        "environment": {**environment(suite.engine_names()), **(environment_extra or {})},
        "xval_version": compare_version(),
    }
    results = ResultsDir.open_for_run(output, suite.source, header, resume)
    if resume:
        remove_stale_temporaries(results.path)  # of a run killed mid-write; we hold the lock
    cases = plan(suite)
    earlier = results.done_records() if resume else {}
    done = {record.case.id for record in earlier.values()}
    todo = [c for c in cases if c.id not in done]
    writer = _Writer(results, suite, progress, earlier)
    frozen_before = gc.get_freeze_count()
    reasons: dict[tuple[str, str], str | None] = {}
    for case in todo:
        key = (case.scene.id, case.engine.label)
        if key not in reasons:
            reasons[key] = skip_reason(case.scene.scene, case.engine)
    runnable = [case for case in todo if reasons[(case.scene.id, case.engine.label)] is None]
    try:
        # Built (its case hosts forked) before the progress bar may start a thread.
        dispatcher = (_Dispatcher(suite, runnable, writer, jobs, executor, timeout or suite.timeout, isolate,
                                  memory_limit) if runnable else None)
        # On whether or not a preload froze anything (an executor passed in preloads nothing): the
        # cases' garbage is collected as usual (compare/run/startup.py).
        startup.resume_collection()
        try:
            progress.start(len(cases), len(cases) - len(todo))
            for case in todo:
                skipped = reasons[(case.scene.id, case.engine.label)]
                if skipped is not None:
                    writer.write(case, None, skipped=skipped)
        except BaseException:
            if dispatcher:
                dispatcher.stop_workers()
            raise
        if dispatcher:
            dispatcher.run()
    finally:
        progress.stop()
        if frozen_before == 0:
            gc.unfreeze()  # what preload_engines froze is collectable again (a program running many suites)
    records = writer.records()
    counts = status_counts(records)
    header = results.finish(counts)
    return RunSummary(results.path, counts, len(todo), len(cases) - len(todo), time.perf_counter() - started, records,
                      header)


def compare_version() -> str:
    try:
        from importlib.metadata import version

        return version("xval")
    except Exception:
        return "unknown"


def _init_worker() -> None:
    """A pool worker's start (cases not isolated: the worker runs the engines itself): die with the
    xval process, and have the reference solver imported (preload_engines did, before the fork)."""
    die_with_parent()
    import engines.reference.reference  # noqa: F401


class _ExecutorPool:
    """A concurrent.futures Executor (a process pool we own, or one given to the runner: a cluster's,
    threads) as the dispatcher drives a HostPool: submit a task, wait for the first done, shut down."""

    depth = 1  # tasks in flight per worker

    def __init__(self, executor: cf.Executor, owned: bool) -> None:
        self.executor = executor
        self.owned = owned

    def submit(self, task: CaseTask | ReferenceTask) -> cf.Future:
        return self.executor.submit(solve_reference if isinstance(task, ReferenceTask) else execute, task)

    @staticmethod
    def wait(pending: Iterable[cf.Future]) -> set[cf.Future]:
        return cf.wait(pending, return_when=cf.FIRST_COMPLETED)[0]

    def shutdown(self, kill: bool = False) -> None:
        """Wait for the workers to end; ``kill``: cancel what waits and SIGKILL the workers of a process
        pool we own, rather than wait for their cases."""
        if not kill:
            self.executor.shutdown(wait=True)
            return
        self.executor.shutdown(wait=False, cancel_futures=True)
        if self.owned:
            for process in list((getattr(self.executor, "_processes", None) or {}).values()):
                with contextlib.suppress(OSError, AttributeError):
                    process.kill()


class _Dispatcher:
    """Submits references and cases, collects them as they finish, rebuilds a broken pool it owns."""

    def __init__(self, suite, cases, writer, jobs, executor, timeout, isolate,
                 memory_limit: int | None = DEFAULT_MEMORY_LIMIT) -> None:
        self.memory_limit = memory_limit
        self.suite = suite
        self.cases = {c.id: c for c in cases}
        self.writer = writer
        # No more hosts or workers than tasks (the cases and one reference per scene of theirs): a
        # --resume with two cases of one scene left forks three at most, not one per core.
        self.jobs = min(jobs or default_jobs(), max(1, len(self.cases) + len({c.scene.id for c in cases})))
        self.timeout = timeout
        self.isolate = isolate
        self.pool = self._new_pool() if executor is None else _ExecutorPool(executor, owned=False)
        self.references: dict[str, Any] = {}  # scene id -> solution, or the exception that stopped it
        self.waiting: dict[str, list[tuple[Case, CaseOutcome]]] = {}
        # Longest first: cost grows like 1/dt.
        self.queue: deque[str] = deque(sorted(self.cases, key=lambda cid: self.cases[cid].dt))
        # Cases lost when the pool broke: each is run again alone, so the one that kills
        # its worker is known and no case that merely shared the pool with it is blamed.
        self.suspects: deque[str] = deque()
        self.alone: str | None = None

    def _new_pool(self) -> HostPool | _ExecutorPool:
        """Case hosts driven from here when cases are isolated (compare.run.hosts); else a pool of
        worker processes that run the engines themselves (a crash then breaks it: see recover)."""
        # fork: hosts and workers inherit the imported engines.
        preload_engines(self.suite, self.cases.values())
        if self.isolate:
            return HostPool(self.jobs)
        # die_with_parent: a kill -9 of xval takes its workers with it.
        return _ExecutorPool(cf.ProcessPoolExecutor(max_workers=self.jobs, mp_context=multiprocessing.get_context("fork"),
                                                    initializer=_init_worker), owned=True)

    def task(self, case: Case) -> CaseTask:
        return CaseTask(
            case_id=case.id,
            engine_id=case.engine.id,
            variant=case.engine.variant,
            options=dict(case.engine.options),
            scene=case.scene.scene,
            dt=case.dt,
            sample_interval=self.suite.sample_interval,
            repeats=self.suite.repeats,
            timeout=self.timeout,
            isolate=self.isolate,
            memory_limit=self.memory_limit,
            command=spec_of(case.engine.engine),
            gradient_wrt=self.suite.gradient_wrt,
        )

    def submit_references(self, scene_ids: list[str]) -> dict[cf.Future, tuple[str, str]]:
        scenes = {s.id: s.scene for s in self.suite.scenes}
        return {
            self.pool.submit(ReferenceTask(
                sid, scenes[sid], self.suite.rtol, self.suite.atol, self.timeout, self.isolate, self.memory_limit,
                sample_dts=tuple(sorted({c.dt for c in self.cases.values() if c.scene.id == sid})),
                sample_interval=self.suite.sample_interval,
            )): ("reference", sid)
            for sid in scene_ids
        }

    def fill(self, pending: dict[cf.Future, tuple[str, str]]) -> dict[cf.Future, tuple[str, str]]:
        """Submit cases while there is room: ``jobs`` × the pool's depth at a time on a pool we own (a
        host runs one and holds the others waiting behind it), all at once otherwise.

        A window on our own pool means a worker's death loses only the cases
        running then, not the whole queue (an executor passed in, e.g. the
        Dask one, keeps its own window). After a break, suspects run one at a
        time with nothing else in flight. Returns ``pending``, or a new dict
        when the pool turned out broken at submission.
        """
        while True:
            try:
                self._fill(pending)
                return pending
            except cf.BrokenExecutor:
                # Its manager saw a worker die before any of our futures said so.
                pending = self.recover(pending)

    def _fill(self, pending: dict[cf.Future, tuple[str, str]]) -> None:
        if self.suspects:
            if not pending:
                self._submit(pending, self.suspects, alone=True)
            return
        in_flight = sum(kind == "case" for kind, _ in pending.values())
        # As many as the pool holds: a host pool's hosts each run one and hold more waiting behind it.
        room = self.jobs * self.pool.depth - in_flight if self.pool.owned else len(self.queue)
        for _ in range(min(room, len(self.queue))):
            self._submit(pending, self.queue)

    def _submit(self, pending: dict[cf.Future, tuple[str, str]], source: deque[str], alone: bool = False) -> None:
        cid = source.popleft()
        try:
            future = self.pool.submit(self.task(self.cases[cid]))
        except cf.BrokenExecutor:
            source.appendleft(cid)  # not run: it goes first once the pool is rebuilt
            raise
        pending[future] = ("case", cid)
        self.alone = cid if alone else None

    def run(self) -> None:
        scene_ids = sorted({c.scene.id for c in self.cases.values()})
        pending = self.fill(self.submit_references(scene_ids))
        try:
            while pending:
                finished = self.pool.wait(pending)
                broken = False
                for future in finished:
                    kind, key = pending.pop(future)
                    try:
                        value = future.result()
                    except RunStopped:
                        raise  # no record for this case: --resume runs it
                    except cf.BrokenExecutor:
                        broken = True
                        pending[future] = (kind, key)  # re-handled below
                        continue
                    except Exception as exc:
                        # A reference that could not be solved is kept as its exception;
                        # a case whose task itself raised (not the engine) is failed.
                        value = exc if kind == "reference" else CaseOutcome(
                            key, None, status=Status.FAILED, message=f"{type(exc).__name__}: {exc}".splitlines()[0]
                        )
                    self.handle(kind, key, value)
                if broken:
                    pending = self.recover(pending)
                pending = self.fill(pending)
        except BaseException:
            # Ctrl-C, SIGTERM or a bug: stop the workers now (their case hosts die with them);
            # finished records are already on disk, and --resume runs the rest.
            self.stop_workers()
            raise
        if self.pool.owned:
            self.pool.shutdown()

    def stop_workers(self) -> None:
        """SIGKILL the case hosts or worker processes of a pool we own, rather than wait for their cases
        to end; an executor we do not own is shut down without waiting."""
        self.pool.shutdown(kill=True)

    def handle(self, kind: str, key: str, value: Any) -> None:
        if kind == "reference":
            value = value if isinstance(value, Exception) else SampledReference(value)
            self.references[key] = value
            for case, outcome in self.waiting.pop(key, []):
                self.writer.write(case, outcome, reference=value)
            return
        case = self.cases[key]
        if case.scene.id in self.references:
            self.writer.write(case, value, reference=self.references[case.scene.id])
        else:
            self.waiting.setdefault(case.scene.id, []).append((case, value))

    def recover(self, pending: dict[cf.Future, tuple[str, str]]) -> dict[cf.Future, tuple[str, str]]:
        """The pool broke (a worker died outside a case's child): rebuild it and run again what was lost.

        Lost cases become suspects, each run again alone (MAX_ATTEMPTS = 2 in
        all); a suspect that breaks the pool while alone is the culprit and is
        recorded failed. With an executor we do not own, everything lost is
        recorded as failed.
        """
        lost = list(pending.values())
        self.pool.shutdown(kill=True)
        reference_ids = [key for kind, key in lost if kind == "reference"]
        case_ids = [key for kind, key in lost if kind == "case"]
        if not self.pool.owned:
            # Not ours to rebuild: what was lost, and what had not been submitted yet, is failed.
            for key in case_ids + list(self.queue):
                self.handle("case", key, CaseOutcome(key, None, status=Status.FAILED, message=LOST_MESSAGE))
            self.queue.clear()
            for scene_id in reference_ids:
                self.handle("reference", scene_id, RuntimeError("the executor broke before the reference was solved"))
            return {}
        for key in case_ids:
            if key == self.alone:
                self.handle("case", key, CaseOutcome(key, None, status=Status.FAILED, message=LOST_MESSAGE))
            else:
                self.suspects.append(key)
        self.alone = None
        self.pool = self._new_pool()
        return self.submit_references(reference_ids)


_preloaded: set[int] = set()


def preload_engines(suite: Suite, cases) -> None:
    """Let each engine of these cases (and the reference, unless every scene's is kept) load what it
    will need once, here, before the pool forks: workers and case hosts inherit it instead of each importing and loading it again
    (numba's kernels, scipy's integrators): Engine.preload, which does nothing by default; a preload
    that fails is ignored (the cases report their own errors)."""
    from engines.reference.reference import ENGINE as REFERENCE, is_kept

    engines = {id(c.engine.engine): c.engine.engine for c in cases if c.engine.engine is not None}
    scenes = list({c.scene.id: c.scene.scene for c in cases}.values())  # those with cases to run
    # The reference solves each of them; its solver (scipy.integrate) is loaded only when some scene's
    # solution is not kept from an earlier run (engines.reference.reference.solve_and_bound_kept).
    if not all(is_kept(scene, suite.rtol, suite.atol) for scene in scenes):
        engines.setdefault(id(REFERENCE), REFERENCE)
    for key, engine in engines.items():
        if key in _preloaded:
            continue
        _preloaded.add(key)
        try:
            engine.preload(scenes)
        except Exception:  # noqa: BLE001 - a preload is an optimisation, never a failure
            continue
    # What is loaded now (modules, numba's kernels, engine libraries' objects) lives as long as the
    # run: moved out of the collector's generations, a full collection no longer walks it (the full
    # collections of a default-suite run walked it again and again), here and in the workers forked
    # from here. bench/bench_harness.py measures what the harness costs.
    # _run_suite unfreezes it when the run ends.
    gc.freeze()
    # The loading is over: collection back on (if the run command turned it off) before the hosts
    # and workers fork, so they collect their cases' garbage too (compare/run/startup.py).
    startup.resume_collection()


class _Writer:
    """Turns outcomes into records (metrics computed here, in the parent) and writes them."""

    def __init__(self, results: ResultsDir, suite: Suite, progress: Progress,
                 earlier: dict[Path, CaseRecord] | None = None) -> None:
        self.results = results
        self.suite = suite
        self.progress = progress
        #: Every record of the directory, by file: an earlier (resumed) run's, read once as the run
        #: started, and those written by this run, kept so the summary need not read them back.
        self.written: dict[Path, CaseRecord] = dict(earlier or {})
        #: Each scene's part of its records, by scene id: built once, shared read-only.
        self.scene_fields: dict[str, SceneFields] = {}

    def write(self, case: Case, outcome: CaseOutcome | None, *, reference: Any = None, skipped: str | None = None) -> None:
        if case.scene.id not in self.scene_fields:
            self.scene_fields[case.scene.id] = SceneFields.of(case.scene.scene)
        record = measure(key_of(case), case.scene.scene, outcome, reference, self.suite, skipped=skipped,
                         scene_part=self.scene_fields[case.scene.id])
        self.written[self.results.write_case(record)] = record
        self.progress.advance(record)

    def records(self) -> list[CaseRecord]:
        """Every record in the results directory, in file order (an earlier run's and this run's)."""
        return [self.written[f] for f in sorted(self.written)]
