"""Running a suite: cases through case hosts or a concurrent.futures.Executor, one record written per
finished case.

The runner plans the cases, solves each scene's reference once, dispatches the cases to case hosts
(compare.run.isolation) or an executor, and turns each answer into a CaseRecord written as it
finishes, so an interrupted run resumes without redoing finished cases.

Details: docs/architecture.md, "Module notes", ``compare/run/runner.py``.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import gc
import math
import multiprocessing
import os
import time
import warnings
from collections import deque
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Iterable

import numpy as np

from engines.adapter import join_messages, scheduled_times, warning_note
from engines.scene.limits import check_case_size
from engines.external.command import spec_of
from engines.errors import Unsupported
from engines.scene.scene import Scene

from compare.run.environment import environment
from compare.run.hosts import HostPool
from compare.run.lock import RunLock
from compare.run import startup
from compare.run.isolation import (DEFAULT_MEMORY_LIMIT, CaseOutcome, CaseTask, ReferenceTask, die_with_parent,
                                   execute, execute_reference)
from compare.results.files import remove_stale_temporaries
from compare.results.metrics import apply_bounds, case_metrics
from compare.run.progress import NullProgress, Progress
from compare.results.declared import MetricInputs, computed_extras
from compare.results.record import CaseKey, CaseRecord, Characteristic, Status, status_counts
from compare.results.series import SeriesView, downsample_indices, round_each
from compare.results.store import Results, ResultsDir, jsonable, now
from compare.suite.reader import EngineSpec, SceneSpec, Suite
from compare.suite.tolerance_axis import tolerance_options, with_tolerance

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


@dataclass(frozen=True)
class Case:
    """One scene × engine variant × dt of a suite; ``position`` is its (scene, engine, dt) index in the suite."""

    scene: SceneSpec
    engine: EngineSpec
    dt: float
    position: tuple[int, int, int] = (0, 0, 0)
    #: On the tolerance axis: the tolerance (already in ``engine.options``); dt is then the largest step.
    tolerance: float | None = None

    @property
    def id(self) -> str:
        return case_id(self.scene.id, self.engine.label, self.dt, self.tolerance)


def case_id(scene_id: str, engine_label: str, dt: float, tolerance: float | None = None) -> str:
    """``bead|mujoco/hinge-rk4|dt=0.001`` (``…|dt=0.01|tol=1e-06`` on the tolerance axis):
    stable across runs, the key ``--resume`` matches on."""
    tail = "" if tolerance is None else f"|tol={tolerance:.12g}"
    return f"{scene_id}|{engine_label}|dt={dt:.12g}{tail}"


def plan(suite: Suite) -> list[Case]:
    """Every case of the suite, scene-major, in the suite's order.

    A variant that takes a tolerance gets one case per suite tolerance instead of one per dt
    (compare/suite/tolerance_axis.py), when the suite sweeps one.
    """
    cases = []
    for i, s in enumerate(suite.scenes):
        for j, e in enumerate(suite.engines):
            names = tolerance_options(e.engine, e.variant, e.options) if suite.tolerances else ()
            if names:
                cases += [Case(s, replace(e, options=with_tolerance(e.options, names, tol)), suite.sample_interval,
                               (i, j, k), tol) for k, tol in enumerate(suite.tolerances)]
            else:
                cases += [Case(s, e, dt, (i, j, k)) for k, dt in enumerate(suite.dts)]
    return cases


def skip_reason(scene: Scene, engine: EngineSpec) -> str | None:
    """Why ``engine`` cannot run ``scene`` (unavailable here, or cannot express it), or None."""
    if engine.engine is None:
        return engine.unavailable
    try:
        engine.engine.check(scene, engine.variant, engine.options)
    except Unsupported as exc:
        return str(exc)
    return None


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
        """The results directory as :func:`compare.results.store.load_results` would read it back, without
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


def check_sizes(suite: Suite) -> None:
    """UserError naming the scene and dt of the first case too big to run (engines/scene/limits.py)."""
    for spec in suite.scenes:
        for dt in suite.dts:
            check_case_size(len(spec.scene.particles), spec.scene.duration, dt, suite.sample_interval,
                            where=f"{suite.path}: scene {spec.id!r}")


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
                            key, None, status="failed", message=f"{type(exc).__name__}: {exc}".splitlines()[0]
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
                self.handle("case", key, CaseOutcome(key, None, status="failed", message=LOST_MESSAGE))
            self.queue.clear()
            for scene_id in reference_ids:
                self.handle("reference", scene_id, RuntimeError("the executor broke before the reference was solved"))
            return {}
        for key in case_ids:
            if key == self.alone:
                self.handle("case", key, CaseOutcome(key, None, status="failed", message=LOST_MESSAGE))
            else:
                self.suspects.append(key)
        self.alone = None
        self.pool = self._new_pool()
        return self.submit_references(reference_ids)


_preloaded: set[int] = set()


def preload_engines(suite: Suite, cases) -> None:
    """Let each engine of these cases (and the reference, unless every scene's is kept) load what it
    will need once, here, before the pool forks: workers and case hosts inherit it instead of each importing and loading it again
    (numba's kernels, scipy's integrators). An engine without ``preload`` is left alone; a preload
    that fails is ignored (the cases report their own errors)."""
    from engines.reference.reference import ENGINE as REFERENCE, is_kept

    engines = {id(c.engine.engine): c.engine.engine for c in cases if c.engine.engine is not None}
    scenes = list({c.scene.id: c.scene.scene for c in cases}.values())  # those with cases to run
    # The reference solves each of them; its solver (scipy.integrate) is loaded only when some scene's
    # solution is not kept from an earlier run (engines.reference.reference.solve_and_bound_kept).
    if not all(is_kept(scene, suite.rtol, suite.atol) for scene in scenes):
        engines.setdefault(id(REFERENCE), REFERENCE)
    for key, engine in engines.items():
        preload = getattr(engine, "preload", None)
        if key in _preloaded or preload is None:
            continue
        _preloaded.add(key)
        try:
            preload(scenes)
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
        #: Each scene's part of its records (scene_fields), by scene id: built once, shared read-only.
        self.scene_fields: dict[str, dict[str, Any]] = {}

    def write(self, case: Case, outcome: CaseOutcome | None, *, reference: Any = None, skipped: str | None = None) -> None:
        if case.scene.id not in self.scene_fields:
            self.scene_fields[case.scene.id] = scene_fields(case.scene.scene)
        record = build_record(case, outcome, reference, self.suite, skipped=skipped,
                              scene_part=self.scene_fields[case.scene.id])
        self.written[self.results.write_case(record)] = record
        self.progress.advance(record)

    def records(self) -> list[CaseRecord]:
        """Every record in the results directory, in file order (an earlier run's and this run's)."""
        return [self.written[f] for f in sorted(self.written)]


def scene_fields(scene: Scene) -> dict[str, Any]:
    """The CaseRecord fields that depend on the scene alone (JSON-ready): the same for every case of it."""
    return {
        "scene": jsonable(scene.to_dict()),
        "scene_hash": scene.content_hash,
        "characteristic": Characteristic(scene.characteristic_length, scene.characteristic_energy),
    }


def key_of(case: Case) -> CaseKey:
    """The record's key of ``case`` (JSON-ready options)."""
    return CaseKey(
        id=case.id, scene_id=case.scene.id, scene_name=case.scene.name, engine=case.engine.label,
        engine_id=case.engine.id, variant=case.engine.variant, options=jsonable(dict(case.engine.options)),
        dt=float(case.dt), position=tuple(int(i) for i in case.position), tolerance=case.tolerance,
    )


def build_record(
    case: Case, outcome: CaseOutcome | None, reference: Any, suite: Suite, *, scene_part: dict[str, Any],
    skipped: str | None = None,
) -> CaseRecord:
    """The record of one case: its metrics, status and message, and its series (a SeriesView of float
    arrays rounded to SERIES_DIGITS significant digits, which ResultsDir.write_case writes as lists).

    reference : the scene's SampledReference, or the exception that kept it
    from being solved (position metrics are then null and the message says why).
    scene_part : ``scene_fields(case.scene.scene)``, kept by the caller for every case of the scene
    (shared, not copied).
    """
    record = CaseRecord(case=key_of(case), status=Status.SKIPPED, message=skipped or "", metrics={}, run_info=None,
                        wall_times=(), elapsed=0.0, series=None, reference=None, finished=now(), **scene_part)
    if outcome is None:
        return record
    record = replace(
        record, status=Status(outcome.status), message=outcome.message or "", elapsed=float(outcome.elapsed),
        wall_times=tuple(float(w) for w in outcome.wall_times),
        cpu_times=tuple(jsonable(outcome.cpu_times)),  # s of CPU per repeat: what the timing gate compares,
        calibrations=tuple(jsonable(outcome.calibrations)),  # in units of this kernel's CPU time, timed beside each
        engine_output=outcome.output.to_dict() if outcome.output else None,  # what its library printed, kept here
    )
    if outcome.trajectory is None:
        return record
    return _measured(record, case, outcome, reference, suite)


def _measured(record: CaseRecord, case: Case, outcome: CaseOutcome, reference: Any, suite: Suite) -> CaseRecord:
    """``record`` with what the trajectory of ``outcome`` gives: run info, reference, metrics, status, series."""
    scene = case.scene.scene
    trajectory = outcome.trajectory
    info = trajectory.info
    status, message = info.status, info.message
    if not (np.isfinite(trajectory.positions).all() and np.isfinite(trajectory.velocities).all()):
        # Engine.simulate already cuts a run at its first non-finite state; an engine
        # that bypasses it (a plug-in overriding simulate) must not pass NaN off as ok.
        finite = (np.isfinite(trajectory.positions).all(axis=(1, 2))
                  & np.isfinite(trajectory.velocities).all(axis=(1, 2)))
        if status == "ok":
            status, message = "unstable", "non-finite state in the returned trajectory"
        trajectory = _truncate(trajectory, int(np.argmin(finite)))
    scheduled = scheduled_times(scene.duration, case.dt, suite.sample_interval)
    n = trajectory.n_samples
    reference_note = ""
    solved: dict[str, Any] | None = None
    horizon = None
    if isinstance(reference, Exception) or reference is None:
        why = reference if reference is not None else "no reference"
        ref_positions = np.full((n, len(scene.particles), 3), math.nan)
        ref_forces = None
        # Every reference-based metric is null, and null here means "not measured", never "never diverged".
        reference_note = f"reference failed ({why}): no reference-based metric"
        message = "; ".join(m for m in (message, reference_note) if m)
    else:
        solution = reference.solution
        # At the scheduled times (shared by every engine of this dt, their samples kept with the
        # solution), of which the trajectory holds the first n; else at an engine's own sample times.
        ref_times = scheduled if np.array_equal(trajectory.t, scheduled[:n]) else trajectory.t
        ref_positions, _, ref_forces = solution.at(ref_times)
        solved = {"rtol": solution.rtol, "atol": solution.atol, "steps": solution.n_steps,
                  "wall_time": solution.wall_time}
        if reference.bound is not None:
            from engines.reference.reference import growth_rate  # loaded already: it made ``reference``

            # The reference's own error bar (m) and horizon (s; None: it holds over the whole run).
            solved.update(reference_error=reference.bound.reference_error,
                          tight_rtol=reference.bound.tight_rtol,
                          horizon_threshold=reference.bound.threshold,
                          lyapunov_exponent=growth_rate(reference.bound.t, reference.bound.difference,
                                                        scene.characteristic_length))
            horizon = reference.bound.reference_horizon
    # A state that ran away (finite, but 1e200 m/s) overflows numpy in the energy: a warning in the case's
    # message, not a line on the terminal.
    with warnings.catch_warnings(record=True) as heard:
        warnings.simplefilter("always")
        metrics, series = case_metrics(
            scene,
            trajectory,
            ref_positions,
            ref_forces,
            scheduled_times=scheduled,
            wall_times=outcome.wall_times,
            delta=suite.delta,
        )
        n_ref = min(n, len(ref_positions))
        extras = computed_extras(MetricInputs(scene, trajectory, ref_positions[:n_ref], series.position_error))
    status, message = _with_note(apply_bounds(status, message, metrics, suite.bounds, scene), reference_note)
    message = join_messages(message, warning_note(heard))
    values = {**metrics.to_dict(), **extras}
    if horizon is not None and n:
        # Past the horizon the reference is not trusted: judge the errors within it, keep the whole run's too.
        values.update(
            within_horizon(scene, trajectory, ref_positions, ref_forces, scheduled, horizon, outcome.wall_times,
                           suite.delta, metrics.to_dict())
        )
    keep = downsample_indices(n)
    # Kept as rounded float arrays: ResultsDir.write_case writes them as lists, and making ~5,000 Python
    # floats a record here was most of the cost of writing it.
    series_arrays = {
        "t": series.t[keep],
        "position_error": series.position_error[keep],
        "energy_drift": series.energy_drift[keep],
        "constraint_error": series.constraint_error[keep],
        "positions": trajectory.positions[keep],
        # The reference at the same samples, so a report can overlay paths without re-solving.
        "reference_positions": ref_positions[:n][keep],
        # For the report's phase plot (angular velocity) and constraint-force plot.
        "velocities": trajectory.velocities[keep],
    }
    if trajectory.constraint_forces is not None:
        series_arrays["constraint_forces"] = trajectory.constraint_forces[keep]
        if ref_forces is not None and len(ref_forces) >= n:
            series_arrays["reference_constraint_forces"] = ref_forces[:n][keep]
    return replace(
        record, status=Status(status), message=message, metrics=jsonable(values), run_info=jsonable(info.to_dict()),
        reference=jsonable(solved), reference_horizon=None if horizon is None else float(horizon),
        series=SeriesView(round_each(series_arrays)),
    )


def _with_note(verdict: tuple[str, str], note: str) -> tuple[str, str]:
    """(status, message) with ``note`` kept in the message (the bounds' verdict replaces the message)."""
    status, message = verdict
    if note and note not in message:
        message = "; ".join(m for m in (message, note) if m)
    return status, message


#: Metrics judged within the reference's horizon (when it ends inside the run); the whole run's values
#: stay in the record as ``<name>_whole_run``.
HORIZON_METRICS = (
    "position_error_final", "position_error_rms", "position_error_linf", "divergence_time",
    "constraint_force_error", "constraint_force_error_relative",
)


def within_horizon(scene: Scene, trajectory: Any, ref_positions: np.ndarray, ref_forces: np.ndarray | None,
                   scheduled: np.ndarray, horizon: float, wall_times: Any, delta: float,
                   whole: dict[str, Any]) -> dict[str, Any]:
    """HORIZON_METRICS over the samples at t ≤ ``horizon`` (s), and the whole run's as ``<name>_whole_run``."""
    k = int(np.searchsorted(scheduled, horizon, side="right"))
    n = min(k, trajectory.n_samples, len(ref_positions))
    if n < 1:
        return {}
    inner, _ = case_metrics(
        scene, _truncate(trajectory, n), ref_positions[:n], None if ref_forces is None else ref_forces[:n],
        scheduled_times=scheduled[:k], wall_times=wall_times, delta=delta,
    )
    values = inner.to_dict()
    out = {f"{name}_whole_run": whole.get(name) for name in HORIZON_METRICS}
    out.update({name: values.get(name) for name in HORIZON_METRICS})
    return out


class SampledReference:
    """A scene's reference: its dense solution, which carries its samples at this run's sample times
    (evaluated by the reference's host, ``ReferenceTask.sample_dts``), and its bound (or None)."""

    def __init__(self, solved: Any) -> None:
        # solve_reference's (solution, bound); a bare solution (no bound) is accepted too.
        self.solution, self.bound = solved if isinstance(solved, tuple) else (solved, None)


def _truncate(trajectory, n: int):
    """The first n samples of ``trajectory``."""
    forces = None if trajectory.constraint_forces is None else trajectory.constraint_forces[:n]
    joints = None if trajectory.joint_states is None else trajectory.joint_states[:n]
    violation = None if trajectory.constraint_violation is None else trajectory.constraint_violation[:n]
    return replace(
        trajectory,
        t=trajectory.t[:n],
        positions=trajectory.positions[:n],
        velocities=trajectory.velocities[:n],
        constraint_forces=forces,
        joint_states=joints,
        constraint_violation=violation,
    )
