"""``xval show``: the tables of a stored results directory, or its cases as CSV / JSON."""

from __future__ import annotations

import click

from compare.results.store import load_results
from compare.results.table import scene_tables, to_csv, to_json
from compare.results.verdict import format_verdicts, scene_verdicts


@click.command("show")
@click.argument("directory", metavar="DIR")
@click.option("--format", "output_format", type=click.Choice(["table", "csv", "json"]), default="table",
              show_default=True, help="table: one row per engine variant per scene; csv/json: one row per case.")
def command(directory, output_format) -> None:
    """Show the results in DIR (the --output of 'xval run')."""
    results = load_results(directory)
    if output_format == "csv":
        click.echo(to_csv(results.records, results.verdict_tolerance), nl=False)
    elif output_format == "json":
        click.echo(to_json(results.records, results.verdict_tolerance), nl=False)
    else:
        header = results.header
        state = "finished " + header["finished"] if header.get("finished") else "unfinished (resume it with --resume)"
        click.echo(f"suite {header['suite']['name']} ({results.path}), {len(results.records)} cases, {state}\n")
        click.echo(scene_tables(results.records, results.verdict_tolerance), nl=False)
        click.echo("\n" + format_verdicts(scene_verdicts(results.sweeps())), nl=False)
