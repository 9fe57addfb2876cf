"""Golden output of the gate for a fixed pair of inputs: the printed table, the Markdown and the JUnit XML.

tests/golden/gate/baseline.json and current.json are baselines of two real
runs of a suite of ours at two orders (bead, dt = 1e-2, 5e-3, 2.5e-3), with
timings, machine and versions fixed, and
``current`` edited to hold one case of every verdict: a doubled position
error and an ok → unstable case (worse), an engine version bump (not
comparable), a dropped case (missing), an added dt (new), halved errors
(better), and untouched cases (unchanged); the doubled-error case is also
3× slower and the unchanged one 2.5× faster, each timed once, so the noise
is unknown and both timing rows are shown as not gated.

After a deliberate change of the output format, regenerate the expected
files with ``XVAL_UPDATE_GOLDEN=1 pytest tests/test_gate_golden.py`` and
review the diff.
"""

from __future__ import annotations

import os

import pytest

from compare.gate.baseline import load_baseline
from compare.gate.gate import gate_results
from compare.gate.report import format_table, to_markdown
from compare.gate.junit import to_junit
from compare.suite.gate_rules import GateSettings

from gate_support import GOLDEN


@pytest.fixture(scope="module")
def report():
    baseline = load_baseline(GOLDEN / "baseline.json")
    current = load_baseline(GOLDEN / "current.json")
    return gate_results(baseline, current, GateSettings(), "baseline.json")


@pytest.mark.parametrize("name, render", [("table.txt", format_table), ("summary.md", to_markdown), ("junit.xml", to_junit)])
def test_golden_output(report, name, render):
    expected = GOLDEN / name
    text = render(report)
    if os.environ.get("XVAL_UPDATE_GOLDEN"):
        expected.write_text(text)
    assert text == expected.read_text()


def test_the_golden_pair_holds_every_verdict(report):
    assert report.counts == {"worse": 2, "not comparable": 1, "missing": 1, "new": 1, "better": 1, "unchanged": 1}
    assert not report.passed
