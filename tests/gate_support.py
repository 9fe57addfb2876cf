"""Shared by tests/test_gate*.py: results made by real runs of tests/gate_suite.toml, and ways to edit copies.

A regression is simulated the way it would appear on disk: a copy of a real
results directory with one case record changed (an error doubled, a status
turned unstable, an engine version bumped), written back with the runner's
own ResultsDir.write_case so the file is exactly what ``xval run`` writes.
"""

from __future__ import annotations

import shutil
import statistics
from pathlib import Path
from typing import Any, Callable


from compare.results.record import CaseRecord
from compare.results.store import ResultsDir, read_json
from compare.run.runner import run_suite
from compare.suite.reader import load_suite
from cli_support import run_cli as xval  # noqa: F401 (tests import it from here)

TESTS = Path(__file__).resolve().parent
SUITE = TESTS / "gate_suite.toml"
GOLDEN = TESTS / "golden" / "gate"
#: The case the regression tests change: the looser "solver" at the middle time step.
CASE = "bead|reference/loose|dt=0.005"


def run(suite: Path, output: Path) -> Path:
    """Run ``suite`` into ``output`` with the real runner (two workers); returns ``output``."""
    run_suite(load_suite(suite), output, jobs=2)
    return output


def copy_results(source: Path, target: Path) -> Path:
    shutil.copytree(source, target)
    return target


def edit_case(directory: Path, case_id: str, change: Callable[[dict[str, Any]], None]) -> dict[str, Any]:
    """Apply ``change`` to the record of ``case_id`` in ``directory`` and write it back; returns the new record."""
    for file in sorted((directory / "cases").glob("*.json")):
        record = read_json(file)  # the raw JSON: tests edit what a file holds
        if record["case"]["id"] == case_id:
            change(record)
            ResultsDir(directory).write_case(CaseRecord.from_json(record, file))
            return record
    raise KeyError(case_id)


def remove_case(directory: Path, case_id: str) -> None:
    for file in (directory / "cases").glob("*.json"):
        if read_json(file)["case"]["id"] == case_id:
            file.unlink()
            return
    raise KeyError(case_id)


def set_timings(record: dict[str, Any], wall_times: list[float]) -> None:
    """Replace the repeats' stepping wall times (s) of ``record`` and the median-based figures made from them."""
    metrics = record["metrics"]
    simulated = metrics["wall_time"] / metrics["cost_per_simulated_second"]
    steps = metrics["steps_per_second"] * metrics["wall_time"]
    median = statistics.median(wall_times)
    record["wall_times"] = list(wall_times)
    # Without CPU times the gate uses its wall-time rule, which these set numbers exercise
    # (the CPU-time rule has its own tests: tests/test_guard_timing.py).
    record.pop("cpu_times", None)
    metrics["wall_time"] = median
    metrics["cost_per_simulated_second"] = median / simulated
    metrics["steps_per_second"] = steps / median


