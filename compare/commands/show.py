"""``xval show``: the tables of a stored results directory, or its cases as CSV / JSON."""

from __future__ import annotations

import click

from compare.cli import output_path
from engines.files import STDOUT, atomic_write_text, check_writable
from compare.results.store import results_inputs

from compare.run.results import load_results
from compare.results.table import scene_tables, to_csv, to_json
from compare.results.verdict import scene_verdicts
from compare.results.verdict_format import format_verdicts


@click.command("show")
@click.argument("directory", metavar="DIR")
@click.option("--format", "output_format", type=click.Choice(["table", "csv", "json"]), default="table",
              show_default=True, help="table: one row per engine variant per scene; csv/json: one row per case.")
@click.option("--output", default=STDOUT, show_default=True, callback=output_path, metavar="FILE",
              help="Where to write: - for standard output, or a file (never one of DIR's own files).")
def command(directory, output_format, output) -> None:
    """Show the results in DIR (the --output of 'xval run')."""
    target = check_writable(output, inputs=results_inputs(directory))
    results = load_results(directory)
    if output_format == "csv":
        text = to_csv(results.records, results.verdict_tolerance)
    elif output_format == "json":
        text = to_json(results.records, results.verdict_tolerance)
    else:
        header = results.header
        state = "finished " + header["finished"] if header.get("finished") else "unfinished (resume it with --resume)"
        text = f"suite {header['suite']['name']} ({results.path}), {len(results.records)} cases, {state}\n\n"
        variant_sweeps = results.sweeps()
        text += scene_tables(variant_sweeps)
        text += "\n" + format_verdicts(scene_verdicts(variant_sweeps))
    if str(target) == STDOUT:
        click.echo(text, nl=False)
    else:
        atomic_write_text(target, text)
