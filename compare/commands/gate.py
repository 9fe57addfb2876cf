"""``xval gate``: compare a results directory with a baseline; exit 1 when a case got worse."""

from __future__ import annotations

import sys
from pathlib import Path

import click


from compare.gate.baseline import build_baseline, load_baseline
from compare.results.files import atomic_write_text, check_writable
from compare.gate.gate import TIMING_MODES, gate_results
from compare.gate.report import format_table, to_markdown
from compare.gate.junit import to_junit
from compare.results.store import load_results
from compare.gate.tolerance import GateSettings
from compare.suite.reader import load_run_settings


def settings_of(directory: Path) -> GateSettings:
    """The [gate] (and legacy [tolerances]) settings of the suite stored with the results
    (read by the suite reader without loading any engine)."""
    return load_run_settings(directory / "suite.toml").gate


@click.command("gate")
@click.argument("directory", metavar="DIR")
@click.option("--baseline", "baseline_path", required=True, metavar="BASELINE.json",
              help="The baseline to compare with (made by 'xval baseline').")
@click.option("--junit", metavar="FILE.xml", default=None, help="Also write JUnit XML: one test case per scene x engine x dt.")
@click.option("--summary", metavar="FILE.md", default=None, help="Also write a Markdown summary (for a CI job summary).")
@click.option("--timing", type=click.Choice(TIMING_MODES), default="gate", show_default=True,
              help="gate: a slowdown past the suite's timing factor and the repeats' spread fails; "
                   "report: timing changes are shown but never fail (for shared or mixed CI machines).")
def command(directory, baseline_path, junit, summary, timing) -> None:
    """Compare the results in DIR with BASELINE.json and print a table of cases marked
    worse, not comparable, missing, new, better or unchanged.

    Exit 0 when no case got worse, 1 when one did, 2 for bad input. A changed
    scene, engine version or engine options makes a case "not comparable":
    reported, not failed. Tolerances come from the suite's [gate] table.
    """
    # Refuse unwritable output paths before any work, like every other verb.
    junit_file = check_writable(junit, "--junit") if junit else None
    summary_file = check_writable(summary, "--summary") if summary else None
    baseline = load_baseline(baseline_path)
    results = load_results(directory)
    current = build_baseline(results, then="gate it")
    report = gate_results(baseline, current, settings_of(Path(directory)), baseline_path, timing=timing)
    made = baseline.get("results") or {}
    click.echo(
        f"baseline {baseline_path}: suite {baseline['suite'].get('name')}, {len(baseline['cases'])} cases, "
        f"made {baseline.get('created')} from commit {made.get('git_commit')}\n"
    )
    click.echo(format_table(report), nl=False)
    if junit_file:
        atomic_write_text(junit_file, to_junit(report))
    if summary_file:
        atomic_write_text(summary_file, to_markdown(report))
    if not report.passed:
        sys.exit(1)
