"""The report's summary: the whole run on one screen, before any scene's section.

One row per scene and one column per engine family: the family's most accurate variant at the scene's equal-cost
budget (compare.results.verdict.best_at_equal_cost), its error, and its cost to reach 1e-6·L; a mark on a cell
whose family has problems worse than "unstable only at the largest dt". Below the table, named one by one with
a link to their evidence: every variant that converges to the wrong answer (inconsistent, with its plateau)
and every engine whose import of a model file disagrees with the model reference (with the links at fault).
What is only unstable at the suite's largest dt is one count per family and scene, expandable.

Built from the scene verdicts the report already computed (reports.verdict) and the parity tables
(reports.parity): nothing is decided here that the sections below do not show.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any, Sequence

from compare.results.verdict import SEVERITIES, family

from reports.numbers import si
from reports.verdict import ProblemItem, SceneVerdictView

#: "link a: …" or "links a, b: …", the start of a parity diagnosis sentence (compare.model.diagnosis.sentences).
_LINKS = re.compile(r"^links? ([^:]+):")


@dataclass(frozen=True)
class FamilyCell:
    """One family on one scene: its most accurate variant at equal cost (``variant``, without the family's
    name, which heads the column; "" when none fits the
    budget), that run's error, that variant's cost to reach the target, and its problems worse than
    "unstable only at the largest dt" (``problems``: count per SEVERITIES name, most severe first)."""

    variant: str
    error: str
    reach: str
    problems: list[tuple[str, int]] = field(default_factory=list)
    note: str = ""

    @property
    def problem_text(self) -> str:
        """"2 wrong answers, 1 unstable below the largest dt"."""
        return ", ".join(f"{n} {name}s" if n > 1 and name == SEVERITIES[0] else f"{n} {name}"
                         for name, n in self.problems)

    @property
    def worst(self) -> int | None:
        """Rank in SEVERITIES of its worst problem, None when it has none."""
        return SEVERITIES.index(self.problems[0][0]) if self.problems else None


@dataclass(frozen=True)
class SceneLine:
    """One scene: its cells by family (None: the family did not compete), the equal-cost budget, and the
    variants unstable only at the largest dt, by family."""

    number: int
    scene_id: str
    budget: str
    target: str
    cells: list[FamilyCell | None]
    largest_only: list[tuple[str, list[str]]]
    largest_dt: float | None

    @property
    def n_largest_only(self) -> int:
        return sum(len(names) for _, names in self.largest_only)


@dataclass(frozen=True)
class Finding:
    """A variant named in the summary, with the text that says what is wrong and the link that shows it."""

    number: int
    scene_id: str
    engine: str
    text: str
    href: str


@dataclass(frozen=True)
class Overview:
    families: list[str]
    lines: list[SceneLine]
    wrong: list[Finding]
    imports: list[Finding]
    #: (SEVERITIES name, count) over every scene for the ranks between a wrong answer and "only at the largest dt".
    others: list[tuple[str, int]]


def _cell(view: SceneVerdictView, name: str) -> FamilyCell | None:
    verdict = view.verdict
    best = next((b for b in verdict.best if b.family == name), None)
    if best is None:
        return None
    counts: dict[str, int] = {}
    for item in view.problems:
        if family(item.engine) == name and item.severity < 3:
            counts[item.severity_name] = counts.get(item.severity_name, 0) + 1
    problems = sorted(counts.items(), key=lambda pair: SEVERITIES.index(pair[0]))
    if best.reading is None:
        note = "no ok run" if best.cheapest is None else f"none within the budget (cheapest {si(best.cheapest, 's/s')})"
        return FamilyCell("", "", "", problems, note)
    reach = next((r for r in verdict.reaches if r.engine == best.reading.engine), None)
    reached = "–" if reach is None else (si(reach.cost, "s/s") if reach.cost is not None else "not reached")
    return FamilyCell(best.reading.engine.split("/", 1)[-1], si(best.reading.error, "m"), reached, problems)


def _largest_only(problems: Sequence[ProblemItem]) -> list[tuple[str, list[str]]]:
    grouped: dict[str, list[str]] = {}
    for item in problems:
        if item.severity == 3:
            grouped.setdefault(family(item.engine), []).append(item.engine)
    return list(grouped.items())


def _links(diagnosis: Sequence[str]) -> list[str]:
    """The link names a parity diagnosis blames, in its order, each once."""
    found: dict[str, None] = {}
    for sentence in diagnosis:
        match = _LINKS.match(sentence)
        if match:
            found.update((name.strip(), None) for name in match.group(1).split(","))
    return list(found)


def import_findings(number: int, scene_id: str, parity: dict[str, Any] | None,
                    ran: set[str] | None = None) -> list[Finding]:
    """Every engine whose import of the scene's model file disagrees with the model reference, with its links;
    ``ran``: the engine families that ran on the scene (the others' import is named, their error is not)."""
    if not parity:
        return []
    found = []
    for row in parity["rows"]:
        if row["agrees"]:
            continue
        links = _links(row["diagnosis"])
        reference = parity["reference"] or "the model reference"
        if not row["cells"] or all(cell["value"] is None for cell in row["cells"]):
            text = f"did not load the file ({row['message'] or 'no message'})"
        else:
            text = f"disagrees with {reference} on this file" + (f": {', '.join(links)}" if links else "")
            text += ("; its error below reflects the import, not the stepping" if ran is None or row["engine"] in ran
                     else " (not in this run)")
        found.append(Finding(number, scene_id, row["engine"], text, f"#parity-{number}"))
    return found


def reconcile(view: SceneVerdictView, parity: dict[str, Any] | None, tolerance: float,
              horizon: float | None, duration: float | None) -> list[str]:
    """Per engine that agrees with the model reference on the file's dynamics (M, bias, q̈) yet errs beyond
    ``tolerance`` (m) at equal cost: why, in words: the stepping, or chaos when the reference's own horizon
    (s) falls inside the run."""
    if not parity:
        return []
    agreeing = {row["engine"] for row in parity["rows"] if row["agrees"]}
    lines = []
    for best in view.verdict.best:
        if best.family not in agreeing or best.reading is None or best.reading.error <= tolerance:
            continue
        text = (f"{best.family} agrees with {parity['reference'] or 'the model reference'} on this file's mass matrix, "
                f"bias and accelerations, yet {best.reading.engine} is {si(best.reading.error, 'm')} off at equal cost: ")
        if horizon is not None and duration is not None and horizon < duration:
            text += (f"the reference itself is reliable only to t = {si(horizon, 's')} (its horizon; the motion is "
                     "chaotic), so this is chaos, not a fault of the import")
        else:
            text += "the import is right, so the difference comes from its stepping"
        lines.append(text)
    return lines


def overview(views: Sequence[SceneVerdictView], parities: dict[int, dict[str, Any] | None]) -> Overview:
    """The summary of every scene's verdict (``views``) and model parity (by scene number)."""
    names: dict[str, None] = {}
    for view in views:
        names.update((b.family, None) for b in view.verdict.best)
    families = list(names)
    lines, wrong, imports = [], [], []
    others: dict[str, int] = {}
    for view in views:
        folded = _largest_only(view.problems)
        lines.append(SceneLine(
            view.number, view.scene_id,
            si(view.verdict.budget, "s/s") if view.verdict.budget is not None else "–",
            si(view.verdict.target, "m"),
            [_cell(view, name) for name in families],
            folded,
            view.dts[0] if folded and view.dts else None,
        ))
        found = import_findings(view.number, view.scene_id, parities.get(view.number),
                                {b.family for b in view.verdict.best})
        imports.extend(found)
        misread = {f.engine for f in found}
        for item in view.problems:
            if item.kind == "inconsistent":
                plateau = f"stops at {si(item.plateau, 'm')}" if item.plateau is not None else "stops falling"
                if item.worst_link:
                    plateau += f", {item.worst_link}"
                if family(item.engine) in misread:
                    plateau += f"; {family(item.engine)}'s import of the file disagrees with the model reference"
                wrong.append(Finding(view.number, view.scene_id, item.engine, plateau, item.href))
            elif 0 < item.severity < 3:
                others[item.severity_name] = others.get(item.severity_name, 0) + 1
    ranked = sorted(others.items(), key=lambda pair: SEVERITIES.index(pair[0]))
    return Overview(families, lines, wrong, imports, ranked)

