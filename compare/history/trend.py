"""Trends across runs: per machine × suite × scene × variant × dt, each metric's value run after run, and its steps.

Steps are found by binary segmentation with a two-sample test against a robust noise estimate
(σ from successive differences, on log10 of positive series); a step must also be a change the
gate would call worse or better. Accuracy series (σ = 0) step at the first changed run; timing
series need MIN_NOISY_RUNS runs, NOISY_SEGMENT runs a side and SIGMAS · σ.

Details: docs/history.md, "Module notes", ``compare/history/trend.py``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from compare.results import declared
from compare.results.declared import TIMING_METRIC, Metric, Tolerance

#: Fewest runs on each side of a step (accuracy metrics: deterministic on one machine).
MIN_SEGMENT = 1
#: For timings (metrics the gate does not judge for accuracy): fewest runs on each side of a step,
#: and fewest runs in the series before steps are looked for (σ from at least 5 differences).
NOISY_SEGMENT = 2
MIN_NOISY_RUNS = 6
#: How many noise standard errors a step must exceed.
SIGMAS = 5.0
#: MAD → standard deviation for normally distributed noise.
MAD_SCALE = 1.4826


@dataclass(frozen=True)
class Step:
    """A step change in a series: ``index`` is the first point after it (into the series' points).

    before, after : medians of the two sides (the metric's unit); ratio : after / before (None when before is 0);
    outcome : "worse" or "better" by the metric's direction; noise : σ of the series (of log10 values when all are positive).
    """

    index: int
    before: float
    after: float
    ratio: float | None
    outcome: str
    noise: float


def _median(values: np.ndarray) -> float:
    return float(np.median(values))


def _exceeds(a: float, b: float, tolerance: Tolerance) -> bool:
    return a > b * (1 + tolerance.rtol) + tolerance.atol


def steps(values: Sequence[float | None], metric: Metric, tolerance: Tolerance | None = None,
          min_segment: int = MIN_SEGMENT, sigmas: float | None = None) -> list[Step]:
    """The step changes in ``values`` (history order; None = no value in that run), by the rule above.

    Returns steps sorted by position; ``Step.index`` indexes ``values`` (gaps included).
    """
    tolerance = tolerance or metric.tolerance
    sigmas = SIGMAS if sigmas is None else sigmas
    positions = [i for i, v in enumerate(values) if v is not None and math.isfinite(v)]
    y = np.array([values[i] for i in positions], dtype=float)
    if not metric.gated:  # a timing: noisy by nature, so its noise must be measurable first
        if len(y) < MIN_NOISY_RUNS:
            return []
        min_segment = max(min_segment, NOISY_SEGMENT)
    if len(y) < 2 * min_segment:
        return []
    z = np.log10(y) if np.all(y > 0) else y
    breaks: list[int] = []

    # Noise from successive differences: a step moves one difference, noise moves them all.
    sigma = MAD_SCALE * _median(np.abs(np.diff(z))) / math.sqrt(2) if len(z) > 2 else 0.0

    def split(lo: int, hi: int) -> None:
        if hi - lo < 2 * min_segment:
            return
        best_k, best_cost = lo + min_segment, math.inf
        for k in range(lo + min_segment, hi - min_segment + 1):
            left, right = z[lo:k], z[k:hi]
            cost = ((left - left.mean()) ** 2).sum() + ((right - right.mean()) ** 2).sum()
            if cost < best_cost - 1e-12:
                best_k, best_cost = k, cost
        k = best_k
        b, a = _median(y[lo:k]), _median(y[k:hi])
        shift = abs(z[k:hi].mean() - z[lo:k].mean())
        noise_bound = sigmas * sigma * math.sqrt(1 / (k - lo) + 1 / (hi - k))
        # A side of two runs is a new level only if both runs are on its side of the midpoint: the median
        # of two is their mean, so one odd run beside an ordinary one would otherwise pass for a level.
        # (One run alone is its own median; three or more have a median one odd run cannot move.)
        middle = (_median(z[lo:k]) + _median(z[k:hi])) / 2
        sign = 1.0 if a > b else -1.0
        held = True
        for side, direction in ((z[lo:k] - middle, -sign), (z[k:hi] - middle, sign)):
            if len(side) == 2 and not np.all(direction * side > 0):
                held = False
        if (_exceeds(a, b, tolerance) or _exceeds(b, a, tolerance)) and shift > noise_bound and held:
            breaks.append(k)
            split(lo, k)
            split(k, hi)

    split(0, len(y))
    # Each step's levels are the medians of the segments on either side of it in the final segmentation.
    edges = [0, *sorted(breaks), len(y)]
    found = []
    for i in range(1, len(edges) - 1):
        b, a = _median(y[edges[i - 1]:edges[i]]), _median(y[edges[i]:edges[i + 1]])
        outcome = "better" if (a > b) == metric.higher_is_better else "worse"
        found.append(Step(positions[edges[i]], b, a, a / b if b != 0 else None, outcome, sigma))
    return found


# -- series out of a history ----------------------------------------------------------------------


def trend_metrics() -> list[Metric]:
    """What the trend page follows: every gated per-case accuracy metric, the observed order, and the cost."""
    chosen = [m for m in declared.METRICS.values() if m.gated]
    return [*chosen, declared.METRICS[TIMING_METRIC]]


@dataclass(frozen=True)
class Point:
    """One run's value in a series. order : the run's position in the history (0 = oldest shown)."""

    run_id: int
    order: int
    commit: str
    date: str
    status: str
    value: float | None


@dataclass(frozen=True)
class Series:
    """One metric of one case (scene × variant × dt) on one machine, across runs; ``steps`` by :func:`steps`;
    position : the case's (scene, engine, dt) indices in the suite, for ordering; fingerprint : the machine's
    (its runs' group in :func:`run_groups`; ``machine`` is its name, which two machines may share)."""

    machine: str
    suite: str
    scene_id: str
    engine: str
    dt: float
    metric: Metric
    points: tuple[Point, ...]
    steps: tuple[Step, ...]
    position: tuple[int, ...] = ()
    fingerprint: str = ""

    @property
    def has_values(self) -> bool:
        return any(p.value is not None for p in self.points)


def run_groups(runs: Sequence[Any], last: int | None = None) -> dict[tuple[str, str], list[Any]]:
    """Stored runs (compare.history.store.StoredRun, in history order) by (machine fingerprint, suite name):
    the runs a trend follows; the last ``last`` of each group when given."""
    groups: dict[tuple[str, str], list[Any]] = {}
    for run in runs:
        groups.setdefault((run.machine.fingerprint, run.suite_name), []).append(run)
    return {key: members[-last:] if last else members for key, members in groups.items()}


def build_series(history: Any, suite: str | None = None, metrics: Sequence[Metric] | None = None,
                 last: int | None = None, groups: Mapping[tuple[str, str], Sequence[Any]] | None = None) -> list[Series]:
    """Every series of the history (compare.history.store.History), machines and suites kept apart.

    last : only the last N runs of each machine × suite. groups : :func:`run_groups` of the history's runs
    (of ``suite``, the last ``last``), when the caller made them already.
    """
    metrics = list(metrics or trend_metrics())
    groups = run_groups(history.runs(suite=suite), last) if groups is None else groups
    out: list[Series] = []
    for (fingerprint, suite_name), runs in groups.items():
        order = {run.id: i for i, run in enumerate(runs)}
        by_run = {run.id: run for run in runs}
        cells: dict[tuple[str, str, float], dict[int, Any]] = {}
        for case in history.cases([r.id for r in runs]):
            cells.setdefault((case.scene_id, case.engine, case.dt), {})[case.run_id] = case
        for (scene_id, engine, dt), stored in cells.items():
            ordered = sorted(stored.values(), key=lambda c: order[c.run_id])
            for metric in metrics:
                points = tuple(
                    Point(
                        c.run_id, order[c.run_id], by_run[c.run_id].origin.short, by_run[c.run_id].started, c.status,
                        _value(c.metrics, metric.name) if c.status == "ok" else None,
                    )
                    for c in ordered
                )
                series = Series(by_run[ordered[0].run_id].machine.name, suite_name, scene_id, engine, dt, metric,
                                points, (), ordered[-1].entry.position, fingerprint)
                if not series.has_values:
                    continue
                found = steps([p.value for p in points], metric)
                out.append(Series(**{**series.__dict__, "steps": tuple(found)}))
    # In the suite's order (scene, engine, largest dt first) within each machine × suite.
    return sorted(out, key=lambda s: (s.machine, s.suite, s.position[:2], s.scene_id, s.engine, -s.dt))


def _value(metrics: Mapping[str, Any], name: str) -> float | None:
    value = metrics.get(name)
    if value is None or isinstance(value, bool):
        return None
    value = float(value)
    return value if math.isfinite(value) else None
