"""A GateReport as JUnit XML, the format CI systems (GitHub, GitLab, Jenkins) display as test results.

One ``<testcase>`` per scene × engine × dt: classname ``xval.<suite>.<scene>``,
name ``<engine> dt=<dt>``. A worse case carries a ``<failure>`` whose
message names the metric and both numbers; not comparable and missing cases
are ``<skipped>`` with the reason (reported, not failed; missing cases are
failures when they fail the gate, compare/gate/gate.py); better, unchanged
and new cases pass, with what changed in ``<system-out>``.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

from compare.gate.gate import CaseResult, GateReport
from compare.gate.report import case_rows, format_value


def _failure_message(case: CaseResult) -> str:
    parts = []
    for change in case.decisive():
        text = (
            f"{change.metric}: baseline {format_value(change.metric, change.baseline)}, "
            f"current {format_value(change.metric, change.current)}"
        )
        if change.limit is not None:
            text += f" (limit {format_value(change.metric, change.limit)} {change.unit})".replace(" )", ")")
        if change.note:
            text += f": {change.note}"
        parts.append(text)
    return "; ".join(parts)


def to_junit(report: GateReport) -> str:
    """The JUnit XML document (UTF-8 text with declaration)."""
    counts = report.counts
    suite = ET.Element(
        "testsuite",
        name=f"xval gate: {report.suite}",
        tests=str(len(report.cases)),
        failures=str(counts["worse"] + (counts["missing"] if report.missing_fails else 0)),
        errors="0",
        skipped=str(counts["not comparable"] + (0 if report.missing_fails else counts["missing"])),
    )
    for case in report.cases:
        element = ET.SubElement(
            suite, "testcase", classname=f"xval.{report.suite}.{case.scene_id}", name=f"{case.engine} dt={case.dt:.3g}"
        )
        detail = "\n".join("  ".join(v for v in row if v) for row in case_rows(case))
        if case.outcome == "worse":
            failure = ET.SubElement(element, "failure", message=f"{case.name}: {_failure_message(case)}", type="worse")
            failure.text = detail
        elif case.outcome == "missing" and report.missing_fails:
            failure = ET.SubElement(element, "failure", message=f"{case.name}: missing: {case.reason}", type="missing")
            failure.text = detail
        elif case.outcome in ("not comparable", "missing"):
            ET.SubElement(element, "skipped", message=f"{case.outcome}: {case.reason}")
        else:
            ET.SubElement(element, "system-out").text = detail
    root = ET.Element("testsuites", name="xval gate", tests=suite.get("tests"), failures=suite.get("failures"))
    root.append(suite)
    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"
