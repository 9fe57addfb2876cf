"""Stepping cost you can reproduce: per case its CPU times (min, spread), per variant a model fitted over its sweep.

Per case i: T_i = the least CPU time (s) over its repeats of the engine's run, n_i its steps. Per variant
the model T_i = a + c·n_i is fitted by Theil–Sen (the median of the pairwise slopes, as
scipy.stats.theilslopes), so one disturbed case cannot move it: a (s) is what a run costs whatever its
length, c (s/step) the per-step cost. A case's cost per simulated second is then steps × c / simulated
time = c/dt for a fixed step: monotone in dt by construction. c's interval is what a rerun needs: at
least a factor RESOLUTION either side (run-to-run noise of CPU time on a shared machine), wider where
leaving out one case moves the fit further. With fewer than MIN_FIT cases timed, c is the median of T_i/n_i (an upper
bound: it carries a) and its interval spans every repeat's T/n, widened likewise.

Records without CPU times (results of an older xval, hand-made records) fall back on their
``cost_per_simulated_second`` metric: then each case is its own model, c = that cost · dt.
"""

from __future__ import annotations

import math
import statistics
from dataclasses import dataclass
from typing import Any, Sequence, TypeGuard

from compare.results.record import CaseRecord, Status

#: Fewest timed cases for the Theil–Sen fit (below it, per-case ratios).
MIN_FIT = 3
#: Least factor either side of a per-step cost its interval spans. One variant's per-step cost moved by up
#: to 1.95× between six runs of the default suite on a shared 2-core machine (tests/fixtures/
#: cost_samples.json; scripts/verdict_example.py prints it): intervals of c/1.7 to 1.7·c from any two such
#: runs overlap (1.7² = 2.9 > 1.95). Theil–Sen's rank interval from one run was often narrower than that
#: (and at times reached down to 0 s/step, from the scatter of runs a few steps long).
RESOLUTION = 1.7


def _positive(value: Any) -> TypeGuard[float]:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value) and value > 0


def cpu_times(record: CaseRecord) -> list[float]:
    """s, the CPU time of each repeat of ``record``'s run (empty when not recorded)."""
    return [float(v) for v in record.cpu_times or () if _positive(v)]


def steps(record: CaseRecord) -> int | None:
    """Steps the engine took (RunInfo.steps), or None."""
    value = (record.run_info or {}).get("steps")
    return int(value) if _positive(value) else None


def step_rate(record: CaseRecord) -> float:
    """Steps per simulated second of ``record``'s run: 1/dt, or on the tolerance axis (an error-controlled
    run, whose dt is only its largest step) its own steps / the scene's duration where both are known."""
    duration, n = (record.scene or {}).get("duration"), steps(record)
    if record.case.tolerance is not None and n and _positive(duration):
        return n / duration
    return 1.0 / record.case.dt


@dataclass(frozen=True)
class CaseCost:
    """One case's timing: least CPU time over repeats (s), spread = max/min − 1, repeats, steps."""

    case_id: str
    cpu_min: float
    spread: float
    repeats: int
    steps: int


def case_cost(record: CaseRecord) -> CaseCost | None:
    """``record``'s CaseCost, or None when it is not ok or was not timed in CPU time."""
    times, n = cpu_times(record), steps(record)
    if record.status is not Status.OK or not times or n is None:
        return None
    return CaseCost(record.case.id, min(times), max(times) / min(times) - 1, len(times), n)


@dataclass(frozen=True)
class CostModel:
    """A variant's stepping cost: per_step c (s/step) in [low, high], overhead a (s per run), how it was found.

    how : "fit" (Theil–Sen over ``cases`` timed cases), "ratio" (too few for a fit) or
    "metric" (no CPU times recorded: each case's own cost_per_simulated_second).
    """

    engine: str
    per_step: float
    low: float
    high: float
    overhead: float
    cases: int
    how: str

    def per_simulated_second(self, rate: float) -> tuple[float, float, float]:
        """(cost, low, high) in s/s at ``rate`` steps per simulated second (:func:`step_rate`)."""
        return self.per_step * rate, self.low * rate, self.high * rate

    def describe(self) -> str:
        """``3.1e-06 s/step [1.8e-06, 5.3e-06]``."""
        return f"{self.per_step:.2g} s/step [{self.low:.2g}, {self.high:.2g}]"


def theil_sen(xs: Sequence[float], ys: Sequence[float]) -> tuple[float, float]:
    """(slope, intercept) of y = intercept + slope·x by Theil–Sen, as scipy.stats.theilslopes gives them
    (slope: the median of the slopes between points of different x; intercept: median y − slope · median x),
    without its per-call overhead. At least two distinct x."""
    slopes = [(ys[j] - ys[i]) / (xs[j] - xs[i]) for i in range(len(xs)) for j in range(i + 1, len(xs)) if xs[j] != xs[i]]
    slope = statistics.median(slopes)
    return slope, statistics.median(ys) - slope * statistics.median(xs)


def _theil_sen(costs: Sequence[CaseCost]) -> tuple[float, float]:
    """(slope s/step, intercept s) of T = a + c·n over ``costs`` by :func:`theil_sen` (the jackknife calls
    this once per case)."""
    return theil_sen([c.steps for c in costs], [c.cpu_min for c in costs])


def _widened(per_step: float, low: float, high: float) -> tuple[float, float]:
    """(low, high) s/step: [low, high] taken out to at least RESOLUTION either side of ``per_step``."""
    return min(low, per_step / RESOLUTION), max(high, per_step * RESOLUTION)


def fit(engine: str, records: Sequence[CaseRecord]) -> CostModel | None:
    """The CostModel of one variant from its case records (any order); None when no case was timed."""
    timed = [(r, c) for r in records if (c := case_cost(r)) is not None]
    costs = [c for _, c in timed]
    if len(costs) >= MIN_FIT and len({c.steps for c in costs}) >= 2:
        slope, intercept = _theil_sen(costs)
        if slope > 0:
            # How far one case moves the fit: the fits leaving out each case in turn (with enough left to fit).
            others = [costs[:k] + costs[k + 1:] for k in range(len(costs))] if len(costs) > MIN_FIT else []
            slopes = [s for rest in others if len({c.steps for c in rest}) >= 2 and (s := _theil_sen(rest)[0]) > 0]
            low, high = _widened(slope, min(slopes, default=slope), max(slopes, default=slope))
            return CostModel(engine, slope, low, high, max(intercept, 0.0), len(costs), "fit")
    if costs:
        ratios = [c.cpu_min / c.steps for c in costs]
        every = [t / c.steps for r, c in timed for t in cpu_times(r)]
        per_step = float(statistics.median(ratios))
        return CostModel(engine, per_step, *_widened(per_step, min(every), max(every)), 0.0, len(costs), "ratio")
    return None


def metric_cost(record: CaseRecord) -> float | None:
    """s/s, the case's own ``cost_per_simulated_second`` metric (records without CPU times), or None."""
    value = record.metrics.get("cost_per_simulated_second") if record.metrics else None
    return float(value) if _positive(value) else None


def modelled(model: CostModel | None, record: CaseRecord) -> tuple[float, float, float] | None:
    """(cost, low, high) s/s of ``record`` under its variant's ``model``; the record's own metric when
    the variant has no model (a run without CPU times: one wall-clock sample, so its interval is at least
    RESOLUTION either side, as a model's is); None without either."""
    if model is None:
        value = metric_cost(record)
        return None if value is None else (value, *_widened(value, value, value))
    return model.per_simulated_second(step_rate(record))
