"""``xval gate``: compare a results directory with a baseline; exit 1 when a case got worse."""

from __future__ import annotations

import sys

import click

from engines.errors import UserError

from compare.gate.baseline import build_baseline, load_baseline
from engines.files import atomic_write_text, check_writable
from compare.results.store import results_inputs
from compare.gate.gate import TIMING_MODES, gate_results
from compare.gate.report import format_table, to_markdown
from compare.cli import history_option
from compare.history.window import DEFAULT_WINDOW, history_baseline
from compare.gate.junit import to_junit
from compare.run.results import load_results


@click.command("gate")
@click.argument("directory", metavar="DIR")
@click.option("--baseline", "baseline_path", default=None, metavar="BASELINE.json",
              help="The baseline to compare with (made by 'xval baseline').")
@history_option(name="history", help="Instead of a baseline: the last runs of the suite on this machine in this history "
                   "(accuracy against the best of them, timing against their spread).")
@click.option("--window", type=click.IntRange(min=1), default=None, metavar="N",
              help=f"With --history: how many of the last runs (default {DEFAULT_WINDOW}).")
@click.option("--junit", metavar="FILE.xml", default=None, help="Also write JUnit XML: one test case per scene x engine x dt.")
@click.option("--summary", metavar="FILE.md", default=None, help="Also write a Markdown summary (for a CI job summary).")
@click.option("--timing", type=click.Choice(TIMING_MODES), default="gate", show_default=True,
              help="gate: a slowdown past the suite's timing factor and the repeats' spread fails; "
                   "report: timing changes are shown but never fail (for shared or mixed CI machines).")
def command(directory, baseline_path, history, window, junit, summary, timing) -> None:
    """Compare the results in DIR with BASELINE.json (or the last runs in a history) and print
    a table of cases marked worse, not comparable, missing, new, better or unchanged.

    Exit 0 when no case got worse, 1 when one did, 2 for bad input. A changed
    scene, engine version or engine options makes a case "not comparable":
    reported, not failed. Tolerances come from the suite's [gate] table.
    """
    # Refuse unwritable output paths before any work, like every other verb.
    # Neither may replace what the gate reads: the baseline, the history, or the results' own files.
    inputs = [p for p in (baseline_path, history) if p is not None] + results_inputs(directory)
    junit_file = check_writable(junit, "--junit", inputs) if junit is not None else None
    summary_file = check_writable(summary, "--summary", inputs) if summary is not None else None
    if (baseline_path is None) == (history is None):
        raise UserError("give either --baseline BASELINE.json or --history FILE (the last runs in a history), not both or neither")
    if window is not None and history is None:
        raise UserError("--window: only with --history FILE")
    baseline = load_baseline(baseline_path) if history is None else None
    results = load_results(directory)
    current = build_baseline(results, then="gate it")
    if history is not None:
        baseline, baseline_path, heading = history_baseline(history, results, window or DEFAULT_WINDOW)
    report = gate_results(baseline, current, results.settings.gate, baseline_path, timing=timing)
    if history is None:
        heading = (f"baseline {baseline_path}: suite {baseline.suite.get('name')}, {len(baseline.cases)} cases, "
                   f"made {baseline.created} from commit {baseline.results.get('git_commit')}")
    click.echo(heading + "\n")
    click.echo(format_table(report), nl=False)
    if junit_file:
        atomic_write_text(junit_file, to_junit(report))
    if summary_file:
        atomic_write_text(summary_file, to_markdown(report))
    if not report.passed:
        sys.exit(1)
