"""``xval baseline``: store the gate-relevant numbers of a finished results directory as one JSON file."""

from __future__ import annotations

import click

from compare.cli import output_path

from compare.gate.baseline import build_baseline, write_baseline
from engines.files import check_writable
from compare.results.store import results_inputs
from compare.run.results import load_results


@click.command("baseline")
@click.argument("directory", metavar="DIR")
@click.option("--output", required=True, metavar="BASELINE.json", callback=output_path,
              help="Baseline file to write (replaced if it exists; never one of DIR's own files).")
def command(directory, output) -> None:
    """Make a baseline of the results in DIR (the --output of 'xval run') for 'xval gate'.

    Per case: status, deterministic metrics (errors, drifts, constraint
    errors, divergence time, observed order), timing with the spread of its
    repeats, and the engine version; keyed by scene content hash, engine,
    variant, options and dt. Commit the file next to the suite it came from.
    """
    target = check_writable(output, inputs=results_inputs(directory))
    results = load_results(directory)
    baseline = build_baseline(results)
    write_baseline(baseline, target)
    statuses: dict[str, int] = {}
    for entry in baseline.cases.values():
        statuses[entry.status.value] = statuses.get(entry.status.value, 0) + 1
    counts = ", ".join(f"{n} {status}" for status, n in sorted(statuses.items()))
    click.echo(f"baseline of suite {baseline.suite['name']}: {len(baseline.cases)} cases ({counts}) -> {target}")
