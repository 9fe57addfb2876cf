"""``xval history``: keep every run in one store (``add``), read it back (``show``), and chart it (``report``).

``report`` lives in reports/ (it renders HTML, and compare/ never imports
reports/); it joins this group through the ``xval.history`` entry-point
group, as reports' own ``xval report`` joins ``xval``.
"""

from __future__ import annotations

import sys
from importlib.metadata import entry_points
from pathlib import Path
from typing import Any

import click

from compare.cli import history_option
from compare.history.location import DEFAULT_LOCATION, LOCATION_VARIABLE
from compare.history.origin import given_origin, recorded_origin, tree_origin
from compare.history.store import AlreadyRecorded, History, StoredRun, baseline_of
from compare.run.results import Results, load_results

HISTORY_HELP = (f"The history: a SQLite file, or a postgresql:// URL (default: ${LOCATION_VARIABLE}, "
                f"else {DEFAULT_LOCATION}).")


class HistoryGroup(click.Group):
    """add and show are built in; further verbs (report) come from the ``xval.history`` entry points."""

    def _plugins(self) -> dict[str, Any]:
        return {e.name: e for e in entry_points(group="xval.history")}

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted({*self.commands, *self._plugins()})

    def get_command(self, ctx: click.Context, name: str) -> click.Command | None:
        if name in self.commands:
            return self.commands[name]
        entry = self._plugins().get(name)
        return None if entry is None else entry.load()


@click.group("history", cls=HistoryGroup)
def command() -> None:
    """Keep every finished run in one history, and follow accuracy and cost across commits."""


def describe(run: StoredRun, cases: int, location: str) -> str:
    dirty = " (uncommitted changes)" if run.origin.dirty else ""
    return (f"history {location}: run {run.id} added: suite {run.suite_name}, {cases} cases, "
            f"commit {run.origin.short}{dirty}, machine {run.machine.fingerprint[:8]} ({run.machine.name})")


def add_directory(directory: str | Path, location: str | None, commit: str | None = None) -> str:
    """Append the finished run in ``directory`` (read from its files); returns the line to print."""
    return add_results(load_results(directory), location, commit)


def add_results(results: Results, location: str | None, commit: str | None = None,
                suite_path: str | Path | None = None) -> str:
    """Append the finished run ``results`` (read back, or held by ``xval run``); returns the line to print.

    The commit: ``commit`` when given; else that of the git working tree holding
    ``suite_path`` (``xval run --history`` passes the suite it just ran); else
    the one run.json recorded (see compare.history.origin).
    """
    document = baseline_of(results)  # an unfinished run is refused before the history is touched
    if commit:
        origin = given_origin(commit)
    else:
        origin = (tree_origin(Path(suite_path).resolve()) if suite_path else None) or recorded_origin(results.header)
    with History.open(location, create=True) as history:
        run = history.add(results, origin, source=str(results.path.resolve()), document=document)
        return describe(run, len(results.records), history.name)


@command.command("add")
@click.argument("directories", metavar="DIR...", nargs=-1, required=True)
@history_option(HISTORY_HELP)
@click.option("--commit", default=None, metavar="SHA[+dirty]",
              help="The commit the run was made at (default: the one DIR/run.json recorded, i.e. xval's checkout).")
def add(directories, location, commit) -> None:
    """Append the finished runs in DIR... (the --output of 'xval run') to the history.

    A run already in the history (the same run.json and case records) is
    refused with one line, the others are still added, and the exit code is
    2; stored runs are never changed.
    """
    refused = 0
    for directory in directories:
        try:
            click.echo(add_directory(directory, location, commit))
        except AlreadyRecorded as exc:
            click.echo(f"xval: error: {exc}", err=True)
            refused += 1
    if refused:
        sys.exit(2)


@command.command("show")
@history_option(HISTORY_HELP)
@click.option("--scene", default=None, metavar="S", help="Only this scene id (shell patterns allowed).")
@click.option("--engine", default=None, metavar="E", help="Only this engine label, e.g. ours/rattle or 'ours/*'.")
@click.option("--metric", "metric_names", multiple=True, metavar="M",
              help="Only this metric (repeatable; default: the short table's metrics). Names: compare/results/declared.py.")
@click.option("--suite", default=None, metavar="NAME", help="Only runs of this suite.")
@click.option("--last", type=click.IntRange(min=1), default=None, metavar="N", help="Only the last N runs.")
@click.option("--format", "output_format", type=click.Choice(["table", "json"]), default="table", show_default=True,
              help="table: aligned text; json: a list of flat objects, one per run × case.")
def show(location, scene, engine, metric_names, suite, last, output_format) -> None:
    """One row per stored run × case: run id, commit, date, machine, scene, engine, dt, status and the metrics."""
    from compare.history.show import Filters, format_table, metric_named, rows, to_json
    from compare.results import declared

    metrics = [metric_named(n) for n in metric_names] or declared.shown()
    with History.open(location) as history:
        table = rows(history, Filters(scene, engine, suite, last), metrics)
        name = history.name
    click.echo(to_json(table) if output_format == "json" else format_table(table, metrics, name), nl=False)
