"""Shared by tests/test_history*.py: one small real run, and synthetic histories made from it.

A synthetic run is the real run with its start time moved and chosen
metrics of chosen variants scaled (accuracy metrics by one factor, the
timing — median cost, wall time, every repeat — by another), as a
regression or machine noise would move them. Runs are added to the store
as :class:`compare.run.results.Results` objects, so no suite is run more
than once per session.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import json
import shutil
import subprocess
from pathlib import Path
from typing import Any, Callable


from compare.history.origin import Origin
from compare.history.store import History, StoredRun
from compare.results.record import CaseRecord
from compare.run.results import Results, load_results
from compare.run.runner import run_suite
from compare.suite.reader import load_suite
from conftest import XVAL, XVAL_ENV
from cli_support import run_cli as xval  # noqa: F401 (tests import it from here)

TESTS = Path(__file__).resolve().parent
#: One scene, two "solvers" (the reference at loose tolerances), three dts, three timing repeats: ~1 s.
SUITE = TESTS / "gate_suite.toml"
#: The variant the regressions are planted in.
ENGINE = "reference/loose"
ERRORS = ("position_error_linf", "position_error_rms", "position_error_final")
TIMING = ("wall_time", "cost_per_simulated_second")
T0 = _dt.datetime(2026, 11, 1, 12, 0, tzinfo=_dt.timezone.utc)


def real_run(output: Path) -> Results:
    run_suite(load_suite(SUITE), output, jobs=1)
    return load_results(output)


def scaled(record: CaseRecord, error: float = 1.0, timing: float = 1.0, tight: bool = False) -> CaseRecord:
    """``record`` with its position errors × error and its timings × timing (steps per second ÷ timing);
    ``tight``: its three repeats set to the median wall time × (0.99, 1, 1.01) first, and its CPU times to
    50 ms × the same (a case long enough for its own timing to be gated, compare.gate.gate.CASE_RESOLUTION)."""
    metrics = dict(record.metrics)
    if not metrics:
        return record
    for name in ERRORS:
        if metrics.get(name) is not None:
            metrics[name] *= error
    for name in TIMING:
        if metrics.get(name) is not None:
            metrics[name] *= timing
    if metrics.get("steps_per_second"):
        metrics["steps_per_second"] /= timing
    repeats = record.wall_times
    if tight and record.metrics.get("wall_time"):
        repeats = tuple(record.metrics["wall_time"] * f for f in (0.99, 1.0, 1.01))
    # The CPU times move with the wall times (the code got slower, the machine did not: calibrations stay).
    cpu = record.cpu_times
    if cpu and tight:
        cpu = tuple(0.05 * f for f in (0.99, 1.0, 1.01))[:len(cpu)]
    return dataclasses.replace(record, metrics=metrics, wall_times=tuple(w * timing for w in repeats),
                               cpu_times=None if cpu is None else tuple(c * timing for c in cpu if c is not None))


def synthetic(base: Results, index: int, error: float = 1.0, timing: float | Callable[[CaseRecord], float] = 1.0,
              engine: str = ENGINE, machine: dict[str, Any] | None = None, tight: bool = False) -> Results:
    """Run number ``index`` of a synthetic history: started ``index`` hours after T0; the errors of
    ``engine`` × error; every case's timing × timing (a number, or a function of the record)."""
    environment = {**base.header.get("environment", {}), **(machine or {})}
    header = {**base.header, "started": (T0 + _dt.timedelta(hours=index)).isoformat(), "environment": environment}
    records = []
    for record in base.records:
        factor = timing(record) if callable(timing) else timing
        records.append(scaled(record, error if record.case.engine == engine else 1.0, factor, tight))
    return dataclasses.replace(base, header=header, records=records)


def origin(index: int, dirty: bool = False) -> Origin:
    """A made-up commit per synthetic run, dated like the run."""
    return Origin(f"{index + 1:040x}", dirty, (T0 + _dt.timedelta(hours=index)).isoformat())


def add(history: History, results: Results, index: int) -> StoredRun:
    return history.add(results, origin(index))


def add_in_process(target: str, base_path: str, index: int, barrier) -> int:
    """A forked writer's task: load the base run, wait for the others at ``barrier``, then add synthetic
    run ``index`` to the history at ``target`` (a file or a database URL), creating it if need be."""
    base = load_results(base_path)
    barrier.wait()
    with History.open(target, create=True) as history:
        return add(history, synthetic(base, index), index).id


def write_results(results: Results, target: Path) -> Path:
    """``results`` as a results directory at ``target`` (run.json, suite.toml, one file per case)."""
    shutil.copytree(results.path, target)
    (target / "run.json").write_text(json.dumps(results.header, indent=1, sort_keys=True) + "\n")
    by_id = {r.case.id: r for r in results.records}
    for file in (target / "cases").glob("*.json"):
        record = CaseRecord.from_json(json.loads(file.read_text()), file)
        file.write_text(json.dumps(by_id[record.case.id].to_json(), allow_nan=False) + "\n")
    return target




def xval_process(*argv: Any, cwd: Path | None = None) -> subprocess.Popen:
    """The CLI in its own process (stdout and stderr captured)."""
    return subprocess.Popen(XVAL + [str(a) for a in argv], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            cwd=cwd, env=XVAL_ENV)
