"""``xval report``: one self-contained HTML file from a results directory (added to ``xval`` by entry point)."""

from __future__ import annotations

import click

from reports.render import DEFAULT_NAME, write_report


@click.command("report")
@click.argument("directory", metavar="DIR")
@click.option("--output", "-o", default=None, metavar="FILE.html",
              help=f"Where to write the report (default: DIR/{DEFAULT_NAME}).")
@click.option("--dt", type=click.FloatRange(min=0, min_open=True), default=None, metavar="S",
              help="Time step of the summary tables and time series (each scene uses its nearest; "
                   "default: per scene, the dt at which most variants are ok).")
def report(directory, output, dt) -> None:
    """Write the HTML report of the results in DIR (the --output of 'xval run').

    The file is self-contained: plots are interactive and it needs no network.
    """
    written = write_report(directory, output, dt)
    click.echo(f"report: {written.path} ({written.size / 1e6:.1f} MB, {written.seconds:.2f} s)")
