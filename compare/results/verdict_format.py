"""The verdict (compare.results.verdict) as text for the terminal and as one JSON document.

``xval verdict DIR`` prints either; ``xval show`` and the end of ``xval run`` print the text; the report
lays out the same SceneVerdict objects. The JSON document (``schema`` "xval-verdict/2") holds per scene:
(with ``front``) the Pareto front, each point with its margin, each variant's cost model (per-step cost with its interval), each variant's cost to
reach 1e-6·L with its interval, each family's winner and the variants tied with it, the focus
comparison (ratio with its interval, tie or not, its sentence), the consistency of every variant, and
the problems, most severe first (each with its severity).
"""

from __future__ import annotations

import textwrap
from typing import Any, Sequence

from compare.results.table import scene_reference
from compare.results.verdict import SEVERITIES, AtBudget, Point, Problem, Reach, SceneVerdict

#: Longest problem text printed in the terminal (the report and the case files have the whole message).
LINE = 140
#: JSON schema of ``xval verdict --format json``.
#: 2: the Pareto front only when asked (``front``): it is the one list that measured time decides point by
#: point, so it can differ between reruns, and everything else in the document does not (docs/metrics.md).
SCHEMA = "xval-verdict/2"


def clip(text: str, width: int = LINE) -> str:
    """``text`` cut at a word boundary to at most ``width`` characters, "…" marking the cut (never mid-number)."""
    return textwrap.shorten(text, width, placeholder=" …")


def _names(engine: str, ties: Sequence[str]) -> str:
    return engine if not ties else f"{engine} (tie: {', '.join(ties)})"


def format_verdicts(verdicts: Sequence[SceneVerdict], problems_only: bool = False) -> str:
    """The closing summary of ``xval run`` as text, one block per scene (``problems_only``: skip the rankings)."""
    lines: list[str] = []
    for verdict in verdicts:
        lines.append(f"{verdict.scene_id}:")
        if not problems_only:
            lines.extend(_rankings(verdict))
        if verdict.problems:
            lines.append(f"  problems ({len(verdict.problems)}, most severe first):")
            lines.extend(_problem_lines(verdict.problems))
        elif not problems_only:
            lines.append("  problems: none")
    return "\n".join(lines) + ("\n" if lines else "")


def _problem_lines(problems: Sequence[Problem]) -> list[str]:
    """One line per problem (compare.results.verdict.ranked order), those unstable only at the suite's largest dt
    (the least severe, often most of the list) folded into one paragraph that names them."""
    lines = [f"    {p.kind:<12} {p.engine}: {clip(p.text)}" for p in problems if not p.largest_only]
    largest = [p for p in problems if p.largest_only]
    if largest:
        head = f"    {SEVERITIES[3]} (dt {largest[0].dts[0]:.3g} s, {len(largest)}): "
        lines.extend(textwrap.wrap(head + ", ".join(p.engine for p in largest), LINE, subsequent_indent=" " * 6,
                                   break_on_hyphens=False))
    return lines


def _rankings(verdict: SceneVerdict) -> list[str]:
    lines = []
    if verdict.winners:
        lines.append(f"  cheapest to reach {verdict.target:.2g} m, per family (cost per simulated s with its interval; "
                     "a tie goes by its member with the fewest steps):")
        width = max(len(w.reach.engine) for w in verdict.winners)
        for winner in verdict.winners:
            lines.append(f"    {winner.reach.engine:<{width}}  {winner.reach.describe()}"
                         + (f"; tie: {', '.join(winner.ties)}" if winner.ties else ""))
    if verdict.budget is not None:
        lines.append(f"  most accurate at equal cost ({verdict.budget:.2g} s per simulated s; each variant's error read "
                     "from its error-cost curve, with the interval its cost's gives; a tie goes by its member "
                     "listed first):")
        width = max((len(b.reading.engine) for b in verdict.best if b.reading is not None), default=0)
        for best in verdict.best:
            if best.reading is None:
                cheapest = "no ok run" if best.cheapest is None else f"cheapest run {best.cheapest:.2g} s/s"
                lines.append(f"    {best.family}: none within the budget ({cheapest})")
            else:
                lines.append(f"    {best.reading.engine:<{width}}  {best.reading.describe()}"
                             + (f"; tie: {', '.join(best.ties)}" if best.ties else ""))
    else:
        lines.append("  no ok run with an error and a cost")
    if verdict.comparison is not None:
        lines.append(f"  {verdict.comparison.describe()}")
    return lines


def _interval(low: float | None, high: float | None) -> list[float] | None:
    return None if low is None or high is None else [low, high]


def _point(p: Point) -> dict[str, Any]:
    return {"engine": p.engine, "dt": p.dt, "tolerance": p.tolerance, "error": p.error, "error_bar": p.error_bar,
            "cost": p.cost, "cost_interval": list(p.interval), "margin": p.margin, "case": p.case_id}


def _at_budget(r: AtBudget) -> dict[str, Any]:
    return {"engine": r.engine, "error": r.error, "error_interval": [r.low, r.high], "error_bar": r.error_bar,
            "how": r.how}


def _reach(r: Reach) -> dict[str, Any]:
    return {"engine": r.engine, "cost": r.cost, "cost_interval": list(r.interval) if r.interval else None,
            "how": r.how, "dts": list(r.dts), "best_error": r.best_error, "plateau": r.plateau,
            "steps_per_simulated_second": r.steps}


def scene_document(verdict: SceneVerdict, front: bool = False) -> dict[str, Any]:
    """One scene's verdict as JSON-ready data (its fields: docs/report.md, "Module notes"); ``front`` adds the
    Pareto front."""
    comparison = verdict.comparison
    same = comparison.at_equal_cost if comparison is not None else None
    return {
        "scene": verdict.scene_id,
        "length": verdict.length,
        "target": verdict.target,
        # The reference's error bar, horizon and Lyapunov estimate, each estimate with its interval.
        "reference": scene_reference(r for s in verdict.variants for r in s.records),
        **({"front": [_point(p) for p in verdict.front]} if front else {}),
        "cost_models": [
            {"engine": s.engine, "per_step": s.cost.per_step, "per_step_interval": [s.cost.low, s.cost.high],
             "overhead": s.cost.overhead, "cases": s.cost.cases, "how": s.cost.how}
            for s in verdict.variants if s.cost is not None],
        "reach": [_reach(r) for r in verdict.reaches],
        "winners": [{"family": w.family, "engine": w.reach.engine, "ties": list(w.ties), "reached": w.reach.reached,
                     "cost": w.reach.cost, "cost_interval": list(w.reach.interval) if w.reach.interval else None}
                    for w in verdict.winners],
        "equal_cost": {
            "budget": verdict.budget,
            "best": [{"family": b.family, **(_at_budget(b.reading) if b.reading else {"engine": None}),
                      "ties": list(b.ties)} for b in verdict.best],
        },
        "comparison": None if comparison is None else {
            "focus_family": comparison.focus_family,
            "focus": None if comparison.focus is None else comparison.focus.engine,
            "focus_ties": list(comparison.focus_ties),
            "other": None if comparison.other is None else comparison.other.engine,
            "other_ties": list(comparison.other_ties),
            "ratio": comparison.ratio,
            "ratio_interval": _interval(comparison.ratio_low, comparison.ratio_high),
            "tie": comparison.tie,
            "shared_cost_range": None if same is None else _interval(same.low, same.high),
            "error_ratio_at_equal_cost": comparison.error_ratio,
            "text": comparison.describe(),
        },
        "consistency": [
            {"engine": s.engine, "consistent": s.consistency.consistent, "plateau": s.consistency.plateau,
             "reason": s.consistency.reason}
            for s in verdict.variants if s.consistency is not None],
        "problems": [{"kind": p.kind, "severity": SEVERITIES[p.severity], "engine": p.engine, "text": p.text,
                      "dts": list(p.dts)}
                     for p in verdict.problems],
    }


def verdict_document(verdicts: Sequence[SceneVerdict], focus: str | None, front: bool = False) -> dict[str, Any]:
    """The verdict of every scene as one JSON-ready object; ``front`` adds each scene's Pareto front."""
    return {"schema": SCHEMA, "focus": focus, "scenes": [scene_document(v, front) for v in verdicts]}
