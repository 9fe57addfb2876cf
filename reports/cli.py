"""``xval report``: one self-contained HTML file from a results directory (added to ``xval`` by entry point)."""

from __future__ import annotations

import click

from reports.render import DEFAULT_NAME, write_report


@click.command("report")
@click.argument("directory", metavar="DIR")
@click.option("--output", "-o", default=None, metavar="FILE.html",
              help=f"Where to write the report (default: DIR/{DEFAULT_NAME}).")
@click.option("--dt", type=click.FloatRange(min=0, min_open=True), default=None, metavar="S",
              help="Time step of the time series and the tables shown first (each scene uses its nearest; "
                   "default: per scene, the dt at which most variants are ok).")
@click.option("--focus", default=None, metavar="FAMILY",
              help="The engine family the verdict compares with the best of the others (the part of a variant's "
                   "name before '/'; default: the suite's first family).")
def report(directory, output, dt, focus) -> None:
    """Write the HTML report of the results in DIR (the --output of 'xval run').

    The file is self-contained: it opens with the verdict per scene, plots are
    interactive and it needs no network.
    """
    written = write_report(directory, output, dt, focus)
    click.echo(f"report: {written.path} ({written.size / 1e6:.1f} MB, {written.seconds:.2f} s)")
