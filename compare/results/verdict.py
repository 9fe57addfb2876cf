"""The verdict of a run, per scene: which variant wins at which budget, which is wrong, which blows up where.

Pure functions of the dt sweeps (:func:`compare.results.sweep.sweeps`), so
``xval run``'s closing summary and the report's verdict section say the same
thing. Nothing here knows any engine by name: an engine *family* is the part
of a variant's label before its first ``/`` (``mujoco`` for
``mujoco/hinge-rk4``), and the family a comparison is made for (the *focus*)
is a parameter, by default the first family of the suite.

Details: docs/report.md, "Module notes", ``compare/results/verdict.py``.
"""

from __future__ import annotations

import math
import statistics
from dataclasses import dataclass, field, replace
from typing import Any, Iterable, Mapping, Sequence, TypeGuard, TypeVar

from compare.results.cost import CostModel, modelled, step_rate
from compare.results.record import PROBLEMS, CaseRecord, Status
from compare.results.sweep import ORDER_METRIC, VariantSweep

#: The target error of "cost to reach", as a fraction of L.
TARGET_FRACTION = 1e-6
#: Problem kinds, in the order they are listed (worst first).
PROBLEM_KINDS = ("inconsistent", "failed", "timeout", "unstable", "wrong gradient", "hidden dissipation")
#: Severity ranks, most severe first (Problem.severity indexes this): a wrong answer, then a run that never
#: finished, then a blow-up at a time step below the suite's largest (a method that should hold there), then a
#: blow-up only at the largest dt (where an explicit method is expected to fail; listed, but collapsed).
SEVERITIES = ("wrong answer", "failed or timed out", "unstable below the largest dt", "unstable only at the largest dt")
_SEVERITY_OF_KIND = {"inconsistent": 0, "wrong gradient": 0, "failed": 1, "timeout": 1, "unstable": 2, "hidden dissipation": 2}


def family(engine: str) -> str:
    """The engine family of a variant label: the part before the first ``/`` (``mujoco/hinge`` -> ``mujoco``)."""
    return engine.split("/", 1)[0]


T = TypeVar("T")


def competitors(sweeps: Iterable[VariantSweep]) -> list[VariantSweep]:
    """The sweeps that compete: not the reference, not skipped throughout."""
    return [s for s in sweeps if not s.is_reference and not s.all_skipped]


def families(sweeps: Iterable[VariantSweep]) -> list[str]:
    """Engine families of the competing ``sweeps``, in the order they first appear (suite order)."""
    seen: dict[str, None] = {}
    for sweep in competitors(sweeps):
        seen.setdefault(family(sweep.engine), None)
    return list(seen)


def _finite_positive(value: object) -> TypeGuard[float]:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value) and value > 0


@dataclass(frozen=True)
class Point:
    """One ok case on the error–cost plane: variant label, dt (s), cost (s/s), max position error (m), case id.

    cost is the variant's cost model at this dt (compare.results.cost), in [cost_low, cost_high] s/s;
    error_bar : m, the reference's own error bar (0 when unknown); rate : steps per simulated second
    (1/dt, or an error-controlled run's own steps / duration): what the cost is c × rate of.
    """

    engine: str
    dt: float
    cost: float
    error: float
    case_id: str
    #: On the tolerance axis (compare/suite/tolerance_axis.py): the case's tolerance; dt is then its largest step.
    tolerance: float | None = None
    cost_low: float | None = None
    cost_high: float | None = None
    error_bar: float = 0.0
    rate: float = 0.0
    #: On the front only (:func:`pareto_front`): how far costs must move for this point to leave it, or None.
    margin: float | None = None

    @property
    def family(self) -> str:
        return family(self.engine)

    @property
    def step(self) -> str:
        """``dt 0.001`` or ``tol 1e-08``: what this point's variant sweeps, padded for a column."""
        return f"dt {self.dt:<9.3g}" if self.tolerance is None else f"tol {self.tolerance:<8.3g}"

    @property
    def interval(self) -> tuple[float, float]:
        """(low, high) s/s of the cost."""
        return (self.cost if self.cost_low is None else self.cost_low,
                self.cost if self.cost_high is None else self.cost_high)


def point(record: CaseRecord, model: CostModel | None = None) -> Point | None:
    """``record`` as a Point (its cost from its variant's ``model``), or None when it is not ok or lacks a
    positive error or cost."""
    if record.status is not Status.OK or not record.has_metrics:
        return None
    error, cost = record.metric(ORDER_METRIC), modelled(model, record)
    if cost is None or not (_finite_positive(cost[0]) and _finite_positive(error)):
        return None
    bar = (record.reference or {}).get("reference_error")
    return Point(record.case.engine, record.case.dt, float(cost[0]), float(error), record.case.id, record.case.tolerance,
                 float(cost[1]), float(cost[2]), float(bar) if _finite_positive(bar) else 0.0, float(step_rate(record)))


def points(sweep: VariantSweep) -> list[Point]:
    """The Points of one variant, largest dt (loosest tolerance, on the tolerance axis) first."""
    found = (point(r, sweep.cost) for r in sorted(
        sweep.records, key=lambda r: -(r.case.dt if r.case.tolerance is None else r.case.tolerance)))
    return [p for p in found if p is not None]


def certainly_cheaper(a: Point, b: Point) -> bool:
    """Whether ``a`` costs less than ``b`` whatever the timing noise: the high end of its cost interval is
    below the low end of ``b``'s, or both are runs of one variant (one per-step cost) and ``a`` takes fewer
    steps per simulated second (and costs less: a variant without a cost model has each run's own cost)."""
    if a.engine == b.engine and 0 < a.rate < b.rate and a.cost < b.cost:
        return True
    return a.interval[1] < b.interval[0]


def pareto_front(sweeps: Iterable[VariantSweep]) -> list[Point]:
    """The Points of every competing variant that no other point beats for certain, most accurate first, each
    with its :func:`front_margin`.

    A point leaves the front only when another is certainly cheaper (:func:`certainly_cheaper`) and errs no
    more; points whose cost intervals overlap all stay. Ordered by error, then by suite order of the variants
    (then the larger dt first): no timing in the order. Membership is still decided by measured costs: a point
    whose margin is within the run-to-run spread of per-step costs can fall either side in a rerun (see
    docs/metrics.md). Costs are not monotone along this list; :func:`lower_envelope` is the staircase.
    """
    rank = {s.engine: k for k, s in enumerate(competitors(sweeps))}
    candidates = [(rank[s.engine], -p.dt, p) for s in competitors(sweeps) for p in points(s)]
    everyone = [q for _, _, q in candidates]
    kept = [(k, dt, replace(p, margin=front_margin(p, everyone))) for k, dt, p in candidates
            if not any(q.error <= p.error and certainly_cheaper(q, p) for q in everyone)]
    return [p for _, _, p in sorted(kept, key=lambda c: (c[2].error, c[0], c[1]))]


def front_margin(p: Point, others: Iterable[Point]) -> float | None:
    """The factor by which costs must move for ``p`` to leave the front: over the other variants' points that
    err no more, the least ratio of the high end of their cost interval to the low end of ``p``'s (≥ 1 while
    none is certainly cheaper). None when no other variant's point errs no more: then nothing timed can beat
    it (its own variant's runs are ordered by their steps). A margin of 1.2 means one cost moving 1.2× ends
    it; per-step costs move up to about 2× between runs on a shared machine (docs/metrics.md)."""
    ratios = [q.interval[1] / p.interval[0] for q in others if q.engine != p.engine and q.error <= p.error]
    return min(ratios) if ratios else None


def lower_envelope(front: Iterable[Point]) -> list[Point]:
    """The classic Pareto staircase through ``front`` at its measured costs, cheapest first: each point errs
    less than every cheaper one. For drawing only: at costs within each other's noise it can move."""
    envelope: list[Point] = []
    for candidate in sorted(front, key=lambda p: (p.cost, p.error)):
        if not envelope or candidate.error < envelope[-1].error:
            envelope.append(candidate)
    return envelope


@dataclass(frozen=True)
class Reach:
    """What one variant costs to bring its error down to ``target`` (m).

    cost : s/s, or None when not reached, in [low, high] (the cost model's interval and the error
    interpolation's). how : "interpolated" (between ``dts``, the bracketing time steps, s), "at most"
    (its cheapest ok run, at ``dts[0]``, is already below), "not reached" or "no ok run".
    best_error : m, its lowest error over its ok runs; plateau : m, where its error stopped falling
    (compare.results.consistency), None while it still falls. steps : steps per simulated second it takes
    to get there (interpolated like the cost; no timing in it), None when not reached.
    """

    engine: str
    target: float
    cost: float | None
    how: str
    dts: tuple[float, ...] = ()
    best_error: float | None = None  # m, the lowest error of any of its ok runs
    low: float | None = None
    high: float | None = None
    plateau: float | None = None
    steps: float | None = None

    @property
    def reached(self) -> bool:
        return self.cost is not None

    @property
    def interval(self) -> tuple[float, float] | None:
        """(low, high) s/s, or None when not reached."""
        if self.cost is None:
            return None
        return (self.cost if self.low is None else self.low, self.cost if self.high is None else self.high)

    def describe(self) -> str:
        if self.cost is None:
            return self.how if self.best_error is None else f"{self.how} (best {self.best_error:.2g} m)"
        low, high = self.interval  # type: ignore[misc]
        if self.how == "at most":
            return f"≤ {self.cost:.2g} s/s [{low:.2g}, {high:.2g}] (already at dt {self.dts[0]:.3g} s)"
        return f"{self.cost:.2g} s/s [{low:.2g}, {high:.2g}] (between dt {self.dts[0]:.3g} and {self.dts[1]:.3g} s)"


def _log_crossing(coarse: Point, fine: Point, target: float, slope: float | None = None) -> float:
    """log cost at which the line through ``coarse`` (with ``slope`` d log cost / d log error, default the
    segment's own) reaches ``target``, kept between the two points (the error falls monotonically there)."""
    if slope is None:
        slope = (math.log(fine.cost) - math.log(coarse.cost)) / (math.log(fine.error) - math.log(coarse.error))
    value = math.log(coarse.cost) + slope * (math.log(target) - math.log(coarse.error))
    return min(max(value, math.log(coarse.cost)), math.log(fine.cost))


def _rate_at(coarse: Point, fine: Point, target: float) -> float | None:
    """Steps per simulated second where the segment coarse–fine reaches ``target`` (m), linear in log–log."""
    if not (coarse.rate > 0 and fine.rate > 0) or coarse.error == fine.error:
        return None
    share = (math.log(target) - math.log(coarse.error)) / (math.log(fine.error) - math.log(coarse.error))
    return math.exp(math.log(coarse.rate) + min(max(share, 0.0), 1.0) * (math.log(fine.rate) - math.log(coarse.rate)))


def _slope(a: Point, b: Point) -> float | None:
    """d log cost / d log error between two points, None when undefined or not falling."""
    if a.error <= 0 or b.error <= 0 or a.error == b.error:
        return None
    slope = (math.log(b.cost) - math.log(a.cost)) / (math.log(b.error) - math.log(a.error))
    return slope if slope < 0 else None


def cost_to_reach(sweep: VariantSweep, target: float) -> Reach:
    """The cost (s/s) at which ``sweep``'s curve first reaches ``target`` (m), with its interval.

    Interpolated linearly in log cost against log error between the bracketing points; the interval
    takes in the cost model's (compare.results.cost) and the crossing read with the neighbouring
    segments' slopes instead (how much the interpolation itself may be off).
    """
    curve = points(sweep)
    plateau = sweep.consistency.plateau if sweep.consistency is not None else None
    if not curve:
        return Reach(sweep.engine, target, None, "no ok run")
    best = min(p.error for p in curve)
    cheapest = min(curve, key=lambda p: p.cost)
    if cheapest.error <= target:
        low, high = cheapest.interval
        return Reach(sweep.engine, target, cheapest.cost, "at most", (cheapest.dt,), best, low, high, plateau,
                     cheapest.rate or None)
    for k, (coarse, fine) in enumerate(zip(curve, curve[1:])):  # dt order: coarse first
        if coarse.error > target >= fine.error:
            middle = _log_crossing(coarse, fine, target)
            guesses = [middle]
            neighbours = ([(curve[k - 1], coarse)] if k > 0 else []) + ([(fine, curve[k + 2])] if k + 2 < len(curve) else [])
            for a, b in neighbours:
                slope = _slope(a, b)
                if slope is not None:
                    guesses.append(_log_crossing(coarse, fine, target, slope))
            cost = math.exp(middle)
            ratio_low, ratio_high = coarse.interval[0] / coarse.cost, coarse.interval[1] / coarse.cost
            return Reach(sweep.engine, target, cost, "interpolated", (coarse.dt, fine.dt), best,
                         math.exp(min(guesses)) * ratio_low, math.exp(max(guesses)) * ratio_high, plateau,
                         _rate_at(coarse, fine, target))
    return Reach(sweep.engine, target, None, "not reached", best_error=best, plateau=plateau)


@dataclass(frozen=True)
class AtBudget:
    """One variant's error at a budget (s/s), read from its error–cost curve (:func:`error_at_budget`).

    error : m, in [low, high] (the cost model's interval carried through the curve); error_bar : m, the
    reference's own (0 when unknown); how : "interpolated" (between two of its runs), "extrapolated" (the
    budget is under its cheapest run, within that run's cost interval: along its first segment's slope) or
    "at its finest" (the budget is past its dearest run: the error of that run, no better).
    """

    engine: str
    budget: float
    error: float
    low: float
    high: float
    error_bar: float = 0.0
    how: str = "interpolated"

    @property
    def family(self) -> str:
        return family(self.engine)

    @property
    def interval(self) -> tuple[float, float]:
        """(low, high) m, widened by the reference's error bar."""
        return self.low - self.error_bar, self.high + self.error_bar

    def describe(self) -> str:
        """``error 1.2e-05 m [4.1e-06, 3.4e-05]``."""
        return f"error {self.error:.2e} m [{self.low:.2g}, {self.high:.2g}]"


def _curve_error(costs: Sequence[float], errors: Sequence[float], cost: float) -> tuple[float, str]:
    """(m, how) the curve's error at ``cost`` (s/s): linear in log error against log cost between the runs
    (``costs`` ascending); under the cheapest, along the first segment when its error falls with cost
    (flat otherwise); past the dearest, the dearest run's error."""
    x, ys = math.log(cost), [math.log(e) for e in errors]
    xs = [math.log(c) for c in costs]
    if x >= xs[-1]:
        return errors[-1], "at its finest"
    if x < xs[0]:
        slope = (ys[1] - ys[0]) / (xs[1] - xs[0]) if len(xs) > 1 and xs[1] > xs[0] else 0.0
        return math.exp(ys[0] + min(slope, 0.0) * (x - xs[0])), "extrapolated"
    k = max(i for i in range(len(xs)) if xs[i] <= x)
    share = (x - xs[k]) / (xs[k + 1] - xs[k]) if xs[k + 1] > xs[k] else 0.0
    return math.exp(ys[k] + share * (ys[k + 1] - ys[k])), "interpolated"


def error_at_budget(curve: Sequence[Point], budget: float) -> AtBudget | None:
    """A variant's error at ``budget`` (s/s) from its Points, or None when even its cheapest run's cost
    interval starts above the budget.

    A variant's costs are its cost model's c × rate with c within [low, high] (compare.results.cost): the
    true curve is the measured one shifted along cost by a factor r in [low/c, high/c]. Read at the
    budget, that gives the error interval: the curve's least and greatest error over costs budget/r. The
    error itself is read at the budget, so a small change of the costs moves it a little, never from one
    run to another.
    """
    if not curve:
        return None
    ordered = sorted(curve, key=lambda p: p.cost)
    cheapest = ordered[0]
    if cheapest.interval[0] > budget:
        return None
    down = statistics.median(p.interval[0] / p.cost for p in ordered)  # ≤ 1
    up = statistics.median(p.interval[1] / p.cost for p in ordered)  # ≥ 1
    costs, errors = [p.cost for p in ordered], [p.error for p in ordered]
    error, how = _curve_error(costs, errors, budget)
    lo_cost, hi_cost = budget / up, budget / down
    read = [error] + [_curve_error(costs, errors, c)[0] for c in (lo_cost, hi_cost, *costs) if lo_cost <= c <= hi_cost]
    bar = statistics.median(p.error_bar for p in ordered)
    return AtBudget(cheapest.engine, budget, error, min(read), max(read), bar, how)


def _overlap(a: Any, b: Any) -> bool:
    """Whether two things' ``interval`` s (low, high) overlap, ends included."""
    return a.interval[0] <= b.interval[1] and b.interval[0] <= a.interval[1]


def chained(seed: T, items: Sequence[T]) -> list[T]:
    """``seed`` and every item linked to it by overlapping intervals (``.interval``), directly or through
    others (a chain), in the order of ``items``: a tie that stays the same whichever member noise puts first."""
    linked, grown = [seed], True
    while grown:
        grown = False
        for item in items:
            if item not in linked and any(_overlap(item, member) for member in linked):
                linked.append(item)
                grown = True
    return [item for item in items if item in linked]


def tied_with(most: AtBudget, readings: Sequence[AtBudget]) -> list[AtBudget]:
    """``most`` and every reading linked to it by overlapping error intervals (:func:`chained`)."""
    return chained(most, readings)


@dataclass(frozen=True)
class Best:
    """A family's variant named most accurate at the common budget, its error there, and its ties.

    reading : the named variant's error at the budget (None: no variant of the family can run within it);
    ties : the family's other variants whose error intervals link up with the most accurate one's, so the
    data cannot order them. The tie is named by its member listed first in the suite (no timing in that
    choice); cheapest : s/s, the family's cheapest run when none fits.
    """

    family: str
    reading: AtBudget | None
    cheapest: float | None = None
    ties: tuple[str, ...] = ()

    @property
    def engine(self) -> str | None:
        return None if self.reading is None else self.reading.engine


def _budget(by_family: Mapping[str, Sequence[Point]]) -> float | None:
    """s/s, the common budget (docs/report.md, "Module notes"), or None when no family has a run."""
    ranges = [(min(p.cost for p in ps), max(p.cost for p in ps)) for ps in by_family.values() if ps]
    if not ranges:
        return None
    common_top = min(high for _, high in ranges)
    every_family = max(low for low, _ in ranges)
    return common_top if every_family <= common_top else every_family


def most_accurate(readings: Sequence[AtBudget]) -> tuple[AtBudget, tuple[str, ...]]:
    """(the named reading, the variants tied with it) among ``readings`` (suite order, at least one)."""
    most = min(readings, key=lambda r: (r.error, r.engine))
    tie = tied_with(most, readings)
    return tie[0], tuple(r.engine for r in tie[1:])


def best_at_equal_cost(sweeps: Sequence[VariantSweep]) -> tuple[float | None, list[Best]]:
    """(budget s/s, per family in suite order its variant most accurate at the budget, read from each
    variant's error–cost curve (:func:`error_at_budget`)); see docs/report.md, "Module notes".

    A family with no ok run gets ``Best(family, None)``.
    """
    curves: dict[str, list[list[Point]]] = {name: [] for name in families(sweeps)}
    for sweep in competitors(sweeps):
        curves[family(sweep.engine)].append(points(sweep))
    budget = _budget({name: [p for curve in cs for p in curve] for name, cs in curves.items()})
    if budget is None:
        return None, [Best(name, None) for name in curves]
    result = []
    for name, cs in curves.items():
        readings = [r for curve in cs if (r := error_at_budget(curve, budget)) is not None]
        if readings:
            named, ties = most_accurate(readings)
            result.append(Best(name, named, ties=ties))
        else:
            result.append(Best(name, None, min((p.cost for c in cs for p in c), default=None)))
    return budget, result


@dataclass(frozen=True)
class EqualCost:
    """Two sides compared at the top of the cost range where both have runs (``high`` s/s; None: no overlap).

    focus / other : each side's variant most accurate there (:func:`most_accurate`), its error read from its
    curve. ratio : other error / focus error (> 1: the focus is more accurate); tie : their error
    intervals overlap.
    """

    low: float | None
    high: float | None
    focus: AtBudget | None
    other: AtBudget | None
    ratio: float | None
    tie: bool


def equal_cost(focus_curves: Sequence[Sequence[Point]], other_curves: Sequence[Sequence[Point]]) -> EqualCost:
    """The focus side's and the other side's most accurate variants at the top of their shared cost range
    (each side: a Point list per variant)."""
    focus_points = [p for c in focus_curves for p in c]
    other_points = [p for c in other_curves for p in c]
    if not focus_points or not other_points:
        return EqualCost(None, None, None, None, None, False)
    low = max(min(p.cost for p in focus_points), min(p.cost for p in other_points))
    high = min(max(p.cost for p in focus_points), max(p.cost for p in other_points))
    if low > high:
        return EqualCost(None, None, None, None, None, False)
    sides = []
    for curves in (focus_curves, other_curves):
        readings = [r for c in curves if (r := error_at_budget(c, high)) is not None]
        sides.append(most_accurate(readings)[0])
    mine, theirs = sides
    return EqualCost(low, high, mine, theirs, theirs.error / mine.error, _overlap(mine, theirs))


@dataclass(frozen=True)
class Comparison:
    """The focus family's best variant against the best of every other family, on cost to reach ``target`` (m).

    focus / other : the Reach each side is named by (:func:`leader`; None: that side has no variant that ran);
    focus_ties / other_ties : the variants tied with it.
    ratio : other cost / focus cost (> 1: the focus is cheaper) in [ratio_low, ratio_high], None unless
    both reached the target; tie : that interval holds 1. at_equal_cost : the two sides over their
    shared cost range. plateaus : m, per variant label the error it stops at (compare.results.consistency).
    """

    focus_family: str
    target: float
    focus: Reach | None
    other: Reach | None
    ratio: float | None
    ratio_low: float | None = None
    ratio_high: float | None = None
    focus_ties: tuple[str, ...] = ()
    other_ties: tuple[str, ...] = ()
    at_equal_cost: EqualCost | None = None

    @property
    def tie(self) -> bool:
        return self.ratio is not None and self.ratio_low is not None and self.ratio_high is not None \
            and self.ratio_low <= 1 <= self.ratio_high

    @property
    def error_ratio(self) -> float | None:
        """At equal cost, the other side's best error / the focus's (> 1: the focus is more accurate)."""
        return self.at_equal_cost.ratio if self.at_equal_cost is not None else None

    def describe(self) -> str:
        """One sentence (two clauses at most)."""
        goal = f"{self.target:.2g} m"
        if self.focus is None:
            return f"no {self.focus_family} variant ran on this scene"
        if self.other is None:
            return f"no engine other than {self.focus_family} ran on this scene"
        mine = _names(self.focus.engine, self.focus_ties)
        theirs = _names(self.other.engine, self.other_ties)
        if self.ratio is not None and self.tie:
            return (f"tie: best {self.focus_family} ({mine}) and the best other engine ({theirs}) reach {goal} at the "
                    f"same cost within the intervals (ratio {self.ratio:.3g} [{self.ratio_low:.3g}, {self.ratio_high:.3g}])")
        if self.ratio is not None:
            factor, low, high = (self.ratio, self.ratio_low, self.ratio_high) if self.ratio >= 1 else (
                1 / self.ratio, 1 / self.ratio_high, 1 / self.ratio_low)  # type: ignore[operator]
            return (f"best {self.focus_family} ({mine}) reaches {goal} {factor:.3g}× [{low:.3g}, {high:.3g}] "
                    f"{'cheaper' if self.ratio >= 1 else 'dearer'} than the best other engine ({theirs})")
        text = f"to reach {goal}: " + "; ".join(f"{r.engine} {r.describe()}" for r in (self.focus, self.other))
        return text + self._equal_cost_clause()

    def _equal_cost_clause(self) -> str:
        """What is true at equal cost: a ratio only where both sides keep converging over the shared range."""
        same = self.at_equal_cost
        if same is None or same.focus is None or same.other is None or same.ratio is None:
            return "; no cost range both sides ran in"
        better, worse = (same.focus, same.other) if same.ratio >= 1 else (same.other, same.focus)
        if same.tie:
            return f"; at equal cost (≤ {same.high:.2g} s/s) {same.focus.engine} and {same.other.engine} tie"
        # A side stuck on a plateau that the other converges past: that, not a ratio at one budget, is the news.
        for stuck_side, going in ((better, worse), (worse, better)):
            stuck = self.plateau_of(stuck_side.engine)
            reach = self.focus if going.engine == self.focus.engine else self.other  # type: ignore[union-attr]
            if stuck is not None and reach is not None and reach.best_error is not None and reach.best_error < stuck:
                where = f" at {reach.describe()}" if reach.cost is not None else ""
                return (f"; {stuck_side.engine} stops at {stuck:.2g} m, {going.engine} keeps converging "
                        f"(to {reach.best_error:.2g} m){where}")
        factor = same.ratio if same.ratio >= 1 else 1 / same.ratio
        return f"; at equal cost (≤ {same.high:.2g} s/s) {better.engine} is {factor:.3g}× more accurate"

    def plateau_of(self, engine: str) -> float | None:
        for reach in (self.focus, self.other):
            if reach is not None and reach.engine == engine:
                return reach.plateau
        return None


def _names(first: str, ties: Sequence[str]) -> str:
    """``a/x`` or ``a/x tied with a/y, a/z``."""
    return first if not ties else f"{first}, tied with {', '.join(ties)}"


def cheapest_tie(reached: Sequence[Reach]) -> list[Reach]:
    """The cheapest of ``reached`` (each with a cost: the lowest low end) and every Reach linked to it by
    overlapping cost intervals (:func:`chained`), in the order given."""
    return chained(min(reached, key=lambda r: r.interval[0]), reached)  # type: ignore[index]


def leader(reaches: Sequence[Reach]) -> tuple[Reach | None, tuple[str, ...]]:
    """(the Reach a group of variants is named by, the variants tied with it); (None, ()) for [].

    Among those that reached: the cheapest's tie (:func:`cheapest_tie`), named by its member that needs the
    fewest steps (then by name): nothing in that choice is timing noise. If none reached, the one that came
    closest (lowest error, then name), tied with none.
    """
    if not reaches:
        return None, ()
    reached = [r for r in reaches if r.cost is not None]
    if reached:
        tie = cheapest_tie(reached)
        named = min(tie, key=lambda r: (r.steps if r.steps is not None else math.inf, r.engine))
        return named, tuple(r.engine for r in tie if r is not named)
    tried = [r for r in reaches if r.best_error is not None]
    return (min(tried, key=lambda r: (r.best_error, r.engine)) if tried else reaches[0]), ()  # type: ignore[arg-type,return-value]


def focus_comparison(sweeps: Sequence[VariantSweep], focus: str, target: float) -> Comparison:
    """How the best ``focus``-family variant compares with the best variant of any other family."""
    return _comparison(sweeps, [cost_to_reach(s, target) for s in competitors(sweeps)], focus, target)


def _comparison(sweeps: Sequence[VariantSweep], reaches: Sequence[Reach], focus: str, target: float) -> Comparison:
    """focus_comparison from each competitor's Reach of ``target``."""
    best_mine, mine_ties = leader([r for r in reaches if family(r.engine) == focus])
    best_theirs, their_ties = leader([r for r in reaches if family(r.engine) != focus])
    ratio = low = high = None
    if best_mine is not None and best_theirs is not None and best_mine.cost and best_theirs.cost:
        ratio = best_theirs.cost / best_mine.cost
        (mine_low, mine_high), (their_low, their_high) = best_mine.interval, best_theirs.interval  # type: ignore[misc]
        low, high = their_low / mine_high, their_high / max(mine_low, 1e-300)
    competing = competitors(sweeps)
    same = equal_cost([points(s) for s in competing if family(s.engine) == focus],
                      [points(s) for s in competing if family(s.engine) != focus])
    return Comparison(focus, target, best_mine, best_theirs, ratio, low, high, mine_ties, their_ties, same)


@dataclass(frozen=True)
class Problem:
    """Something wrong with one variant on one scene.

    kind : one of PROBLEM_KINDS. dts : the time steps it concerns, s, largest first
    (empty for a property of the whole sweep). text : one line. case_ids : the cases that show it.
    """

    scene_id: str
    engine: str
    kind: str
    text: str
    dts: tuple[float, ...] = ()
    case_ids: tuple[str, ...] = ()
    #: True for an unstable problem whose only dt is the largest of the suite (the least severe kind).
    largest_only: bool = False

    @property
    def severity(self) -> int:
        """Its rank in SEVERITIES (0: a wrong answer, the most severe)."""
        return 3 if self.largest_only else _SEVERITY_OF_KIND.get(self.kind, 2)


def _dts(values: Iterable[float]) -> str:
    return ", ".join(f"{dt:.3g}" for dt in values)


def problems(sweeps: Sequence[VariantSweep]) -> list[Problem]:
    """Every problem of the competing ``sweeps`` (and the reference's own failures), most severe first (:func:`ranked`)."""
    found: list[Problem] = []
    largest = max((r.case.dt for s in sweeps for r in s.records if r.status is not Status.SKIPPED), default=None)
    for sweep in sweeps:
        if sweep.all_skipped:
            continue
        verdict = sweep.consistency
        if verdict is not None and verdict.consistent is False and not sweep.is_reference:
            ok = sweep.ok_records
            found.append(Problem(sweep.scene_id, sweep.engine, "inconsistent", verdict.reason,
                                 case_ids=tuple(r.case.id for r in ok)))
        for status in PROBLEMS:  # found is sorted by PROBLEM_KINDS below
            kind = status.value
            hit = sorted((r for r in sweep.records if r.status is status), key=lambda r: -r.case.dt)
            if not hit:
                continue
            dts = tuple(r.case.dt for r in hit)
            text = f"{kind} at dt {_dts(dts)} s"
            if kind == "unstable" and largest is not None and dts[0] == largest:
                stable = [r.case.dt for r in sweep.ok_records]
                text += " (the largest dt of the suite" + (f"; ok from dt {max(stable):.3g} s)" if stable else "; never ok)")
            message = next((r.message for r in hit if r.message), "")
            if message:
                text += f": {message}"
            found.append(Problem(sweep.scene_id, sweep.engine, kind, text, dts, tuple(r.case.id for r in hit),
                                 largest_only=kind == "unstable" and dts == (largest,)))
        wrong = sorted((r for r in sweep.records if (r.metrics or {}).get("gradient_wrong") == 1), key=lambda r: -r.case.dt)
        if wrong:  # [gradients]: d outputs / d wrt does not converge to the reference's (docs/gradients.md)
            dts = tuple(r.case.dt for r in wrong)
            found.append(Problem(sweep.scene_id, sweep.engine, "wrong gradient",
                                 f"wrong gradient at dt {_dts(dts)} s: it does not converge to the reference's",
                                 dts, tuple(r.case.id for r in wrong)))
    return ranked(found)


def ranked(found: Iterable[Problem]) -> list[Problem]:
    """``found`` most severe first (SEVERITIES), then by kind (PROBLEM_KINDS); stable within a rank."""
    return sorted(found, key=lambda p: (p.severity, PROBLEM_KINDS.index(p.kind) if p.kind in PROBLEM_KINDS else 99))


@dataclass(frozen=True)
class SceneVerdict:
    """Everything the verdict says about one scene (each quantity: docs/report.md, "Module notes").

    length : L, m. target : TARGET_FRACTION · L, m. reaches : per competing variant, suite order.
    budget : s/s, the equal-cost budget; best : per family its most accurate run within it.
    """

    scene_id: str
    length: float
    target: float
    front: list[Point]
    reaches: list[Reach]
    budget: float | None
    best: list[Best]
    comparison: Comparison | None
    problems: list[Problem] = field(default_factory=list)
    winners: list[Winner] = field(default_factory=list)
    variants: list[VariantSweep] = field(default_factory=list)


@dataclass(frozen=True)
class Winner:
    """A family's variant named for reaching the target most cheaply (:func:`leader`), and those tied with it."""

    family: str
    reach: Reach
    ties: tuple[str, ...] = ()


def family_winners(reaches: Sequence[Reach]) -> list[Winner]:
    """Per family (in the order of ``reaches``) its Winner."""
    names: dict[str, None] = {}
    for reach in reaches:
        names.setdefault(family(reach.engine), None)
    found = []
    for name in names:
        best, ties = leader([r for r in reaches if family(r.engine) == name])
        if best is not None:
            found.append(Winner(name, best, ties))
    return found


def default_focus(sweeps: Iterable[VariantSweep]) -> str | None:
    """The first engine family of the suite (suite order), or None when no engine competes."""
    names = families(sweeps)
    return names[0] if names else None


def scene_verdicts(sweeps: Sequence[VariantSweep], focus: str | None = None,
                   target_fraction: float = TARGET_FRACTION) -> list[SceneVerdict]:
    """Per scene (suite order) its verdict; ``focus`` : the family compared (default: the suite's first)."""
    focus = focus if focus is not None else default_focus(sweeps)
    by_scene: dict[str, list[VariantSweep]] = {}
    for sweep in sweeps:
        by_scene.setdefault(sweep.scene_id, []).append(sweep)
    verdicts = []
    for scene_id, members in by_scene.items():
        length = members[0].records[0].characteristic.length
        target = target_fraction * length
        budget, best = best_at_equal_cost(members)
        reaches = [cost_to_reach(s, target) for s in competitors(members)]
        present = families(members)
        comparison = (_comparison(members, reaches, focus, target)
                      if focus is not None and focus in present and len(present) > 1 else None)
        verdicts.append(SceneVerdict(scene_id, length, target, pareto_front(members), reaches, budget, best,
                                     comparison, problems(members), family_winners(reaches), competitors(members)))
    return verdicts
