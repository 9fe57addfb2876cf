"""A GateReport as text: the table ``xval gate`` prints and the Markdown for a CI job summary.

One row per decisive change: a case that got worse in two metrics has two
rows, each naming the case, the metric and both numbers, so a CI log line
found by grep is complete on its own. Unchanged cases show their headline
(max position error, or status); timing changes that cannot fail the gate
(another machine, ``--timing report``, a single repeat) are shown with the
reason, labelled ``slower (not gated)`` / ``faster (not gated)`` rather than
with the case's outcome, so a row that starts ``worse`` always failed the gate.
"""

from __future__ import annotations

import html
from typing import Any

from compare.gate.gate import CaseResult, Change, GateReport
from compare.text import inert

COLUMNS = ("outcome", "scene", "engine", "dt", "metric", "baseline", "current", "note")
#: The metric an unchanged case is summarised by.
HEADLINE = "position_error_linf"
#: The label of a row whose change is shown but cannot fail the gate (only timing can be ungated).
NOT_GATED = {"worse": "slower (not gated)", "better": "faster (not gated)"}


def format_value(metric: str, value: Any) -> str:
    if value is None:
        return "never" if metric == "divergence_time" else "-"
    if isinstance(value, str):
        return value
    if metric == "observed_order":
        return f"{value:.2f}"
    return f"{value:.3e}"


def _note(change: Change) -> str:
    """The reason text of a row: the rule's own note (status, timing), else the ratio and, if worse, the limit."""
    if change.note:
        return change.note
    parts = []
    if isinstance(change.baseline, (int, float)) and isinstance(change.current, (int, float)) and change.baseline > 0:
        parts.append(f"×{change.current / change.baseline:.2f}")
    if change.outcome == "worse" and change.limit is not None:
        parts.append(f"limit {format_value(change.metric, change.limit)}")
    return ", ".join(parts)


def case_rows(case: CaseResult) -> list[list[str]]:
    """The table rows of one case (columns COLUMNS)."""
    where = [case.scene_id, case.engine, f"{case.dt:.3g}"]
    if case.outcome in ("not comparable", "missing", "new"):
        return [[case.outcome, *where, "-", case.baseline_status or "-", case.current_status or "-", case.reason]]
    shown: list[Change] = case.decisive()
    if case.outcome == "unchanged":
        headline = [c for c in case.changes if c.metric == HEADLINE] or [c for c in case.changes if c.metric == "status"]
        shown = headline[:1]
    shown += [c for c in case.changes if not c.gated and c.outcome != "unchanged"]
    return [
        [case.outcome if c.gated else NOT_GATED[c.outcome], *where,
         c.metric, format_value(c.metric, c.baseline), format_value(c.metric, c.current), _note(c)]
        for c in shown
    ]


def _table(rows: list[list[str]]) -> list[str]:
    widths = [max(len(c), *(len(r[i]) for r in rows)) if rows else len(c) for i, c in enumerate(COLUMNS)]
    lines = ["  ".join(c.ljust(w) for c, w in zip(COLUMNS, widths)).rstrip()]
    lines += ["  ".join(v.ljust(w) for v, w in zip(row, widths)).rstrip() for row in rows]
    return lines


def summary_line(report: GateReport) -> str:
    """``gate FAILED: 1 worse, …`` / ``gate passed: …`` with the counts of every outcome."""
    counts = ", ".join(f"{n} {outcome}" for outcome, n in report.counts.items())
    state = "passed" if report.passed else "FAILED"
    timing = f"timing factor {report.settings.timing_factor:g}"
    timing += f", not gated: {report.timing_note}" if report.timing_note else ", gated"
    return f"gate {state} (suite {report.suite}): {counts} ({timing})"


def format_table(report: GateReport) -> str:
    """The printed table, then notes and the summary line."""
    rows = [row for case in report.cases for row in case_rows(case)]
    lines = _table(rows)
    lines += [f"note: {note}" for note in report.notes]
    lines.append(summary_line(report))
    return "\n".join(lines) + "\n"


def _md_escape(text: str) -> str:
    """A table cell or line of gate.md: HTML-escaped (a label ``<img src=x onerror=...>`` is text),
    control characters made visible, and pipes escaped so a cell cannot split the row."""
    return html.escape(inert(text), quote=False).replace("|", "\\|")


def to_markdown(report: GateReport) -> str:
    """Markdown for a CI job summary: pass or fail, counts, the changed cases, the unchanged ones folded away."""
    state = "passed" if report.passed else "FAILED"
    lines = [f"## xval gate {state}: suite {_md_escape(report.suite)}", ""]
    lines.append(", ".join(f"**{n}** {outcome}" for outcome, n in report.counts.items() if n) + ".")
    if report.timing_note:
        lines.append(f"Timing not gated: {_md_escape(report.timing_note)}.")
    lines += [f"Note: {_md_escape(note)}" for note in report.notes]
    header = ["| " + " | ".join(COLUMNS) + " |", "|" + "---|" * len(COLUMNS)]

    def rows_of(cases: list[CaseResult]) -> list[str]:
        return ["| " + " | ".join(_md_escape(v) for v in row) + " |" for case in cases for row in case_rows(case)]

    changed = [c for c in report.cases if c.outcome != "unchanged"]
    unchanged = [c for c in report.cases if c.outcome == "unchanged"]
    lines.append("")
    lines += header + rows_of(changed) if changed else ["No case changed."]
    if unchanged:
        lines += ["", f"<details><summary>{len(unchanged)} unchanged case{'s' * (len(unchanged) != 1)}</summary>", ""]
        lines += header + rows_of(unchanged) + ["", "</details>"]
    return "\n".join(lines) + "\n"
