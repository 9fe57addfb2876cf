"""The gate against the recent past: a results directory against the last N runs of its suite on the same machine.

It builds a baseline from the stored entries of a window of runs and hands it to the same
:func:`compare.gate.gate.gate_results`, so every rule is the gate's own; only the baseline each
case is held to changes.

Details: docs/history.md, "Module notes", ``compare/history/window.py``.
"""

from __future__ import annotations

import statistics
from dataclasses import dataclass, replace
from typing import Any, Sequence

from compare.gate.baseline import Baseline
from compare.gate.entry import BaselineEntry, Timing, engine_version, record_key
from compare.results.record import Status
from compare.suite.gate_rules import RULES
from compare.history.origin import machine_of
from compare.history.store import History, StoredRun
from compare.run.results import Results

#: Runs in the window when --window is not given.
DEFAULT_WINDOW = 5


@dataclass(frozen=True)
class Window:
    """The runs a gate compares with (oldest first) and the baseline made from them."""

    runs: tuple[StoredRun, ...]
    document: Baseline
    machine: str
    suite: str

    def describe(self, history: str) -> str:
        """One line for the gate's output."""
        if not self.runs:
            return (f"history {history}: no earlier run of suite {self.suite!r} on this machine ({self.machine}); "
                    f"every case is new")
        first, last = self.runs[0], self.runs[-1]
        return (f"history {history}: window of the last {len(self.runs)} runs of suite {self.suite!r} on this machine "
                f"({self.machine}), runs {first.id}–{last.id}, commits {first.origin.short}..{last.origin.short}")


def window_runs(history: History, results: Results, size: int) -> list[StoredRun]:
    """The last ``size`` runs of the results' suite on the results' machine, oldest first, the run itself excluded."""
    machine = machine_of(results.header)
    suite = str((results.header.get("suite") or {}).get("name", ""))
    itself = history.find(results)
    runs = [r for r in history.runs(suite=suite, machine=machine.fingerprint) if itself is None or r.id != itself.id]
    return runs[-size:] if size > 0 else []


def _best(values: Sequence[Any], rule: Any) -> Any:
    """The best of one metric's values across the window (None-aware, by the metric's declaration)."""
    if rule.none_means == "infinite" and any(v is None for v in values):
        return None
    numbers = [v for v in values if v is not None]
    if not numbers:
        return None
    return max(numbers) if rule.higher_is_better else min(numbers)


def _window_timing(timings: Sequence[Timing | None]) -> Timing | None:
    """The window's timing: median of the runs' costs; repeats and spread over every repeat of every run;
    each run's calibrated cost (``per_run``: the distribution the timing gate compares with, not its best
    run), the median of the runs' CPU seconds, and the latest calibrated run's repeats."""
    timed = [t for t in timings if t]
    if not timed:
        return None
    repeats = tuple(c for t in timed for c in t.repeats or (t.cost,))
    calibrated = [t for t in timed if t.calibrated_runs]
    seconds = [t.seconds for t in timed if t.seconds is not None]
    latest = calibrated[-1] if calibrated else None
    return Timing(statistics.median(t.cost for t in timed), repeats, (min(repeats), max(repeats)),
                  cpu=latest.cpu if latest else None, calibration=latest.calibration if latest else None,
                  runs=len(timed), seconds=statistics.median(seconds) if seconds else None,
                  per_run=tuple(v for t in calibrated for v in t.calibrated_runs) or None)


def combine(entries: Sequence[BaselineEntry], current_version: str | None) -> BaselineEntry:
    """One baseline entry from a case's entries across the window (oldest first): the best of each."""
    same = [e for e in entries if e.engine_version == current_version]
    if not same:
        return entries[-1]  # the engine version changed: "not comparable", as against a baseline file
    ok = [e for e in same if e.status is Status.OK]
    if not ok:
        return same[-1]  # never ok in the window: its latest state is the baseline
    with_metrics = [e for e in ok if e.metrics]
    metrics = ok[-1].metrics
    if with_metrics:
        metrics = {name: _best([e.metric(name) for e in with_metrics], rule) for name, rule in RULES.items()}
    verdicts = [e.consistent for e in same]
    return replace(ok[-1], metrics=metrics, timing=_window_timing([e.timing for e in ok]),
                   consistent=True if True in verdicts else False if False in verdicts else None)


def window_baseline(history: History, results: Results, size: int = DEFAULT_WINDOW) -> Window:
    """The baseline of the window for ``results`` (what each case is held to: docs/history.md, "Module notes")."""
    machine = machine_of(results.header)
    suite = str((results.header.get("suite") or {}).get("name", ""))
    runs = window_runs(history, results, size)
    stored = [history.cases([run.id]) for run in runs]  # oldest first; each run's cases read once
    per_key: dict[str, list[BaselineEntry]] = {}
    for run_cases in stored:
        for case in run_cases:
            per_key.setdefault(case.case_key, []).append(case.entry)
    latest_keys = {c.case_key for c in stored[-1]} if stored else set()
    current_versions = _current_versions(results)
    cases = {}
    for key, entries in per_key.items():
        if key in latest_keys or key in current_versions:
            cases[key] = combine(entries, current_versions.get(key, entries[-1].engine_version))
    ids = tuple(r.id for r in runs)
    document = runs[-1].as_baseline(cases, window=ids) if runs else Baseline(
        suite={"name": suite, "fingerprint": (results.header.get("suite") or {}).get("fingerprint"), "path": None},
        cases=cases, machine=dict(machine.fields), window=ids,
    )
    return Window(tuple(runs), document, machine.name, suite)


def _current_versions(results: Results) -> dict[str, str | None]:
    """Case key -> engine version of the run being gated."""
    return {record_key(r): engine_version(r, results.header) for r in results.records}


def history_baseline(location: str, results: Results, size: int = DEFAULT_WINDOW) -> tuple[Baseline, str, str]:
    """For ``xval gate --history``: (the window's baseline, a name for messages, the heading line)."""
    with History.open(location) as history:
        window = window_baseline(history, results, size)
        return window.document, f"{history.name} (window of {len(window.runs)} runs)", window.describe(history.name)
