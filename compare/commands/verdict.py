"""``xval verdict``: the verdict of a stored results directory, as text or as one JSON document."""

from __future__ import annotations

import json

import click

from compare.cli import output_path
from engines.files import STDOUT, atomic_write_text, check_writable
from compare.results.store import results_inputs
from compare.run.results import load_results
from compare.results.verdict import default_focus, families, scene_verdicts
from compare.results.verdict_format import format_verdicts, verdict_document
from engines.errors import UserError


@click.command("verdict")
@click.argument("directory", metavar="DIR")
@click.option("--format", "output_format", type=click.Choice(["table", "json"]), default="table", show_default=True,
              help="table: the verdict as `xval run` ends with it; json: one document with every figure and interval.")
@click.option("--focus", default=None, metavar="FAMILY",
              help="The engine family compared with the best of the others (default: the suite's first).")
@click.option("--front", is_flag=True,
              help="JSON: add each scene's Pareto front, each point with its margin. It is decided by measured "
                   "costs, so points at its edge can differ between reruns; the rest of the document does not.")
@click.option("--output", default=STDOUT, show_default=True, callback=output_path, metavar="FILE",
              help="Where to write: - for standard output, or a file (never one of DIR's own files).")
def command(directory, output_format, focus, front, output) -> None:
    """Per scene of DIR (the --output of 'xval run'): the Pareto front, each family's best variant, the cost to
    reach 1e-6·L with its interval, ties, and the problems."""
    target = check_writable(output, inputs=results_inputs(directory))
    variant_sweeps = load_results(directory).sweeps()
    present = families(variant_sweeps)
    if focus is not None and focus not in present:
        raise UserError(f"--focus {focus}: no such engine family in {directory}; choose one of {', '.join(present)}")
    focus = focus or default_focus(variant_sweeps)
    verdicts = scene_verdicts(variant_sweeps, focus)
    if output_format == "json":
        text = json.dumps(verdict_document(verdicts, focus, front), indent=1) + "\n"
    else:
        text = format_verdicts(verdicts)
    if str(target) == STDOUT:
        click.echo(text, nl=False)
    else:
        atomic_write_text(target, text)
