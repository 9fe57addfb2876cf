"""The verdict of a run, per scene: which variant wins at which budget, which is wrong, which blows up where.

Pure functions of the dt sweeps (:func:`compare.results.sweep.sweeps`), so
``xval run``'s closing summary and the report's verdict section say the same
thing. Nothing here knows any engine by name: an engine *family* is the part
of a variant's label before its first ``/`` (``mujoco`` for
``mujoco/hinge-rk4``), and the family a comparison is made for (the *focus*)
is a parameter, by default the first family of the suite.

Quantities (per scene; L = the scene's characteristic length, m):

- a *point* is one ``ok`` case with a positive, finite max position error
  (m) and stepping cost (s of wall time per simulated s);
- the *Pareto front* is the set of points no other point beats in both cost
  and error: for each budget, the most accurate run that fits in it;
- the *cost to reach* a target error (default 1e-6·L) is read off a
  variant's own curve (its ok points in dt order), interpolated linearly in
  log cost against log error between the last point above the target and the
  first at or below it; "at most" when its cheapest point is already below,
  None ("not reached") when no point is;
- *equal cost*: the budget is the top of the cost range every engine family
  covered (the smallest, over families, of each family's dearest run); when
  the families' ranges do not overlap, the smallest budget at which every
  family has a run (the largest, over families, of each family's cheapest
  run). Per family, its most accurate run within that budget;
- *problems*: a variant that is inconsistent (converges to something other
  than the reference, compare.results.consistency), unstable (the dts at
  which it was, the suite's largest first), failed or timed out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Iterable, Sequence

from compare.results.declared import TIMING_METRIC
from compare.results.record import PROBLEMS, CaseRecord, Status
from compare.results.sweep import ORDER_METRIC, VariantSweep

#: The target error of "cost to reach", as a fraction of L.
TARGET_FRACTION = 1e-6
#: Problem kinds, in the order they are listed (worst first).
PROBLEM_KINDS = ("inconsistent", "failed", "timeout", "unstable", "hidden dissipation")


def family(engine: str) -> str:
    """The engine family of a variant label: the part before the first ``/`` (``mujoco/hinge`` -> ``mujoco``)."""
    return engine.split("/", 1)[0]


def competitors(sweeps: Iterable[VariantSweep]) -> list[VariantSweep]:
    """The sweeps that compete: not the reference, not skipped throughout."""
    return [s for s in sweeps if not s.is_reference and not s.all_skipped]


def families(sweeps: Iterable[VariantSweep]) -> list[str]:
    """Engine families of the competing ``sweeps``, in the order they first appear (suite order)."""
    seen: dict[str, None] = {}
    for sweep in competitors(sweeps):
        seen.setdefault(family(sweep.engine), None)
    return list(seen)


def _finite_positive(value: object) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value) and value > 0


@dataclass(frozen=True)
class Point:
    """One ok case on the error–cost plane: variant label, dt (s), cost (s/s), max position error (m), case id."""

    engine: str
    dt: float
    cost: float
    error: float
    case_id: str
    #: On the tolerance axis (compare/suite/tolerance_axis.py): the case's tolerance; dt is then its largest step.
    tolerance: float | None = None

    @property
    def family(self) -> str:
        return family(self.engine)

    @property
    def step(self) -> str:
        """``dt 0.001`` or ``tol 1e-08``: what this point's variant sweeps, padded for a column."""
        return f"dt {self.dt:<9.3g}" if self.tolerance is None else f"tol {self.tolerance:<8.3g}"


def point(record: CaseRecord) -> Point | None:
    """``record`` as a Point, or None when it is not ok or lacks a positive error or cost."""
    if record.status is not Status.OK or not record.has_metrics:
        return None
    # The cost axis: stepping wall time per simulated second, s/s.
    cost, error = record.metric(TIMING_METRIC), record.metric(ORDER_METRIC)
    if not (_finite_positive(cost) and _finite_positive(error)):
        return None
    return Point(record.case.engine, record.case.dt, float(cost), float(error), record.case.id, record.case.tolerance)


def points(sweep: VariantSweep) -> list[Point]:
    """The Points of one variant, largest dt (loosest tolerance, on the tolerance axis) first."""
    found = (point(r) for r in sorted(
        sweep.records, key=lambda r: -(r.case.dt if r.case.tolerance is None else r.case.tolerance)))
    return [p for p in found if p is not None]


def pareto_front(sweeps: Iterable[VariantSweep]) -> list[Point]:
    """The non-dominated Points of every competing variant, cheapest first (error falls along the list).

    A point is on the front when no other point costs no more and errs strictly less,
    or costs strictly less and errs no more.
    """
    candidates = sorted((p for s in competitors(sweeps) for p in points(s)), key=lambda p: (p.cost, p.error))
    front: list[Point] = []
    for candidate in candidates:
        if not front or candidate.error < front[-1].error:
            front.append(candidate)
    return front


@dataclass(frozen=True)
class Reach:
    """What one variant costs to bring its error down to ``target`` (m).

    cost : s/s, or None when not reached. how : "interpolated" (between ``dts``, the
    bracketing time steps, s), "at most" (its cheapest ok run, at ``dts[0]``, is already
    below), "not reached" or "no ok run". best_error : m, its lowest error over its ok runs.
    """

    engine: str
    target: float
    cost: float | None
    how: str
    dts: tuple[float, ...] = ()
    best_error: float | None = None  # m, the lowest error of any of its ok runs

    @property
    def reached(self) -> bool:
        return self.cost is not None

    def describe(self) -> str:
        if self.cost is None:
            return self.how if self.best_error is None else f"{self.how} (best {self.best_error:.2g} m)"
        if self.how == "at most":
            return f"≤ {self.cost:.2g} s/s (already at dt {self.dts[0]:g} s)"
        return f"{self.cost:.2g} s/s (between dt {self.dts[0]:g} and {self.dts[1]:g} s)"


def cost_to_reach(sweep: VariantSweep, target: float) -> Reach:
    """The cost (s/s) at which ``sweep``'s curve first reaches ``target`` (m); see the module docstring."""
    curve = points(sweep)
    if not curve:
        return Reach(sweep.engine, target, None, "no ok run")
    best = min(p.error for p in curve)
    cheapest = min(curve, key=lambda p: p.cost)
    if cheapest.error <= target:
        return Reach(sweep.engine, target, cheapest.cost, "at most", (cheapest.dt,), best)
    for coarse, fine in zip(curve, curve[1:]):  # dt order: coarse first
        if coarse.error > target >= fine.error:
            fraction = math.log(coarse.error / target) / math.log(coarse.error / fine.error)
            cost = math.exp(math.log(coarse.cost) + fraction * (math.log(fine.cost) - math.log(coarse.cost)))
            return Reach(sweep.engine, target, cost, "interpolated", (coarse.dt, fine.dt), best)
    return Reach(sweep.engine, target, None, "not reached", best_error=best)


@dataclass(frozen=True)
class Best:
    """A family's most accurate run within the common budget (``point`` None: none of its runs fits)."""

    family: str
    point: Point | None
    cheapest: float | None = None  # s/s, the family's cheapest run when none fits


def best_at_equal_cost(sweeps: Sequence[VariantSweep]) -> tuple[float | None, list[Best]]:
    """(budget s/s, per family in suite order its most accurate run costing ≤ budget); see the module docstring.

    A family with no ok run gets ``Best(family, None)``.
    """
    by_family: dict[str, list[Point]] = {name: [] for name in families(sweeps)}
    for sweep in competitors(sweeps):
        by_family[family(sweep.engine)].extend(points(sweep))
    ranges = [(min(p.cost for p in ps), max(p.cost for p in ps)) for ps in by_family.values() if ps]
    if not ranges:
        return None, [Best(name, None) for name in by_family]
    common_top = min(high for _, high in ranges)
    every_family = max(low for low, _ in ranges)
    budget = common_top if every_family <= common_top else every_family
    result = []
    for name, ps in by_family.items():
        within = [p for p in ps if p.cost <= budget]
        if within:
            result.append(Best(name, min(within, key=lambda p: (p.error, p.cost))))
        else:
            result.append(Best(name, None, min((p.cost for p in ps), default=None)))
    return budget, result


@dataclass(frozen=True)
class Comparison:
    """The focus family's best variant against the best of every other family, on cost to reach ``target`` (m).

    focus / other : the cheapest Reach of each side (None: that side has no variant that ran).
    ratio : other cost / focus cost (> 1: the focus is cheaper), None unless both reached the target.
    error_ratio : at equal cost, other family's best error / the focus's (> 1: the focus is more accurate).
    """

    focus_family: str
    target: float
    focus: Reach | None
    other: Reach | None
    ratio: float | None
    error_ratio: float | None

    def describe(self) -> str:
        """One sentence."""
        goal = f"{self.target:.2g} m"
        if self.focus is None:
            return f"no {self.focus_family} variant ran on this scene"
        if self.other is None:
            return f"no engine other than {self.focus_family} ran on this scene"
        if self.ratio is not None:
            faster = "cheaper" if self.ratio >= 1 else "dearer"
            factor = self.ratio if self.ratio >= 1 else 1 / self.ratio
            return (f"best {self.focus_family} ({self.focus.engine}) reaches {goal} {factor:.3g}× {faster} than the "
                    f"best other engine ({self.other.engine})")
        side = []
        for reach in (self.focus, self.other):
            side.append(f"{reach.engine} {reach.describe()}")
        text = f"to reach {goal}: " + "; ".join(side)
        if self.error_ratio is not None and self.error_ratio >= 1:
            text += f"; at equal cost the best {self.focus_family} variant is {self.error_ratio:.3g}× more accurate"
        elif self.error_ratio is not None:
            text += f"; at equal cost the best other engine is {1 / self.error_ratio:.3g}× more accurate"
        return text


def _cheapest(reaches: list[Reach]) -> Reach | None:
    """The cheapest Reach that reached; if none did, the one that came closest (lowest error); None for []."""
    if not reaches:
        return None
    reached = [r for r in reaches if r.cost is not None]
    if reached:
        return min(reached, key=lambda r: r.cost)  # type: ignore[arg-type,return-value]
    tried = [r for r in reaches if r.best_error is not None]
    return min(tried, key=lambda r: r.best_error) if tried else reaches[0]  # type: ignore[arg-type,return-value]


def focus_comparison(sweeps: Sequence[VariantSweep], focus: str, target: float) -> Comparison:
    """How the best ``focus``-family variant compares with the best variant of any other family."""
    reaches = [cost_to_reach(s, target) for s in competitors(sweeps)]
    return _comparison(reaches, best_at_equal_cost(sweeps)[1], focus, target)


def _comparison(reaches: Sequence[Reach], bests: Sequence[Best], focus: str, target: float) -> Comparison:
    """focus_comparison from each competitor's Reach of ``target`` and best_at_equal_cost's rows."""
    best_mine = _cheapest([r for r in reaches if family(r.engine) == focus])
    best_theirs = _cheapest([r for r in reaches if family(r.engine) != focus])
    ratio = None
    if best_mine is not None and best_theirs is not None and best_mine.cost and best_theirs.cost:
        ratio = best_theirs.cost / best_mine.cost
    mine_error = [b.point.error for b in bests if b.family == focus and b.point is not None]
    their_error = [b.point.error for b in bests if b.family != focus and b.point is not None]
    error_ratio = min(their_error) / mine_error[0] if mine_error and their_error else None
    return Comparison(focus, target, best_mine, best_theirs, ratio, error_ratio)


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


def _dts(values: Iterable[float]) -> str:
    return ", ".join(f"{dt:.3g}" for dt in values)


def problems(sweeps: Sequence[VariantSweep]) -> list[Problem]:
    """Every problem of the competing ``sweeps`` (and the reference's own failures), worst kind first."""
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
            found.append(Problem(sweep.scene_id, sweep.engine, kind, text, dts, tuple(r.case.id for r in hit)))
    found.sort(key=lambda p: PROBLEM_KINDS.index(p.kind))
    return found


@dataclass(frozen=True)
class SceneVerdict:
    """Everything the verdict says about one scene (see the module docstring for each quantity).

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
        comparison = (_comparison(reaches, best, focus, target)
                      if focus is not None and focus in present and len(present) > 1 else None)
        verdicts.append(SceneVerdict(scene_id, length, target, pareto_front(members), reaches, budget, best,
                                     comparison, problems(members)))
    return verdicts


#: Longest problem text printed in the terminal (the report and the case files have the whole message).
LINE = 140


def format_verdicts(verdicts: Sequence[SceneVerdict], problems_only: bool = False) -> str:
    """The closing summary of ``xval run`` as text, one block per scene (``problems_only``: skip the rankings)."""
    lines: list[str] = []
    for verdict in verdicts:
        lines.append(f"{verdict.scene_id}:")
        if not problems_only:
            if verdict.budget is not None:
                lines.append(f"  most accurate at equal cost (≤ {verdict.budget:.2g} s per simulated s):")
                width = max((len(b.point.engine) for b in verdict.best if b.point is not None), default=0)
                for best in verdict.best:
                    if best.point is None:
                        cheapest = "no ok run" if best.cheapest is None else f"cheapest run {best.cheapest:.2g} s/s"
                        lines.append(f"    {best.family}: none within the budget ({cheapest})")
                    else:
                        p = best.point
                        lines.append(f"    {p.engine:<{width}}  {p.step} error {p.error:.2e} m  cost {p.cost:.2e} s/s")
            else:
                lines.append("  no ok run with an error and a cost")
            if verdict.comparison is not None:
                lines.append(f"  {verdict.comparison.describe()}")
        if verdict.problems:
            lines.append(f"  problems ({len(verdict.problems)}):")
            for problem in verdict.problems:
                text = problem.text if len(problem.text) <= LINE else problem.text[:LINE - 1] + "…"
                lines.append(f"    {problem.kind:<12} {problem.engine}: {text}")
        elif not problems_only:
            lines.append("  problems: none")
    return "\n".join(lines) + ("\n" if lines else "")
