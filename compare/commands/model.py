"""``xval model check``: where each engine's import of a robot model disagrees with Pinocchio's dynamics."""

from __future__ import annotations

import json

import click

from compare.model.isolation import DEFAULT_TIMEOUT
from compare.model.parity import BASES, QUANTITIES, TOLERANCE, CheckCrashed, ParityReport, check
from engines.model.importers import ENGINES


@click.group("model")
def command() -> None:
    """Robot models (URDF, MJCF): how each engine imports them."""


@command.command("check")
@click.argument("model", metavar="MODEL")
@click.option("--engine", "engines", multiple=True, type=click.Choice(ENGINES),
              help="Engine to compare with Pinocchio (repeatable; default: all).")
@click.option("--states", default=100, show_default=True, type=click.IntRange(1, 100000),
              help="Number of sampled states (q within limits, v, tau).")
@click.option("--seed", default=0, show_default=True, type=int, help="Seed of the sampled states.")
@click.option("--balance-inertia", is_flag=True,
              help="Let MuJoCo balance inertias that violate A + B >= C (its balanceinertia) instead of refusing them.")
@click.option("--timeout", default=DEFAULT_TIMEOUT, show_default=True, type=click.FloatRange(min=0, min_open=True),
              help="Seconds each engine (and the reference) may take before it is killed.")
@click.option("--base", type=click.Choice(BASES), default="fixed", show_default=True,
              help="A URDF's root link welded to the world (fixed) or free (floating); an MJCF says its own.")
@click.option("--format", "output_format", type=click.Choice(["table", "json"]), default="table", show_default=True)
def check_command(model, engines, states, seed, balance_inertia, timeout, base, output_format) -> None:
    """Compare each engine's M(q), bias b(q, v) and forward dynamics with Pinocchio's on MODEL.

    MODEL is a URDF or MJCF file, or pybullet_data:<path> for a model PyBullet
    ships (e.g. pybullet_data:kuka_iiwa/model.urdf). Exit code 0 when every
    engine agrees (M and bias within 1e-6 relative, the forward dynamics within
    the bound M's conditioning gives), 1 when one does not (or cannot load the
    file, or crashed: each engine runs in a process of its own), 2 for bad input.
    """
    try:
        report = check(model, tuple(engines) or ENGINES, states=states, seed=seed, balance_inertia=balance_inertia,
                       timeout=timeout, base=base)
    except CheckCrashed as exc:
        click.echo(f"xval: model {model}: {exc}; nothing was compared", err=True)
        raise click.exceptions.Exit(1) from None
    click.echo(json.dumps(report.to_dict(), indent=1, ensure_ascii=False) if output_format == "json" else render(report))
    raise click.exceptions.Exit(report.exit_code)


def render(report: ParityReport) -> str:
    count = len(report.moving_joints)
    lines = [f"model {report.model} ({report.name}: {count} moving joint{'' if count == 1 else 's'}), model reference "
             f"{report.model_reference.engine} {report.model_reference.version}, {report.states} states "
             f"(seed {report.seed})"]
    header = ["engine", "version", "loaded", "M", "bias", "forward", "agrees"]
    rows = [[e.engine, e.version, "yes" if e.loaded else "no",
             *(_cell(getattr(e, q)) for q in QUANTITIES), "yes" if e.agrees else "no"] for e in report.engines]
    widths = [max(len(r[k]) for r in [header, *rows]) for k in range(len(header))]
    lines += ["  ".join(c.ljust(w) if k < 3 else c.rjust(w) for k, (c, w) in enumerate(zip(r, widths))).rstrip()
              for r in [header, *rows]]
    lines.append(f"M, bias, forward: largest |engine - {report.model_reference.engine}| over states and entries, "
                 f"divided by the largest |{report.model_reference.engine}|; agrees when M and bias are <= "
                 f"{TOLERANCE:g} and forward <= {_bound(report.forward_tolerance)} ({TOLERANCE:g} times what M's "
                 f"conditioning amplifies)")
    for e in report.engines:
        if e.message:
            lines.append(f"{e.engine}: {e.message}")
    if report.diagnosis or report.model_reference.diagnosis:
        lines.append("diagnosis (mass properties at q = 0 in the world frame, against the file):")
        lines += [f"  {line}" for line in (*report.diagnosis, *report.model_reference.diagnosis)]
    lines += [f"note: {note}" for note in report.notes]
    return "\n".join(lines)


def _cell(value: float | None) -> str:
    return "-" if value is None else f"{value:.1e}"


def _bound(value: float) -> str:
    return f"{value:.1e}" if value != float("inf") else "inf (M singular: not judged)"


@command.command("survey")
@click.argument("paths", nargs=-1, required=True, metavar="PATH...")
@click.option("--jobs", "-j", type=click.IntRange(min=1), default=None,
              help="Files checked at once (default: one per core).")
@click.option("--scheduler", default=None, metavar="tcp://HOST:PORT|local[:N]",
              help="Check the files on a Dask cluster: a scheduler's address, or local[:N] for a local one.")
@click.option("--states", default=100, show_default=True, type=click.IntRange(1, 100000),
              help="Number of sampled states per file.")
@click.option("--seed", default=0, show_default=True, type=int, help="Seed of the sampled states.")
@click.option("--timeout", default=DEFAULT_TIMEOUT, show_default=True, type=click.FloatRange(min=0, min_open=True),
              help="Seconds each engine (and the reference) may take on one file before it is killed.")
@click.option("--quiet", "-q", is_flag=True, help="No progress while running.")
@click.option("--format", "output_format", type=click.Choice(["table", "json"]), default="table", show_default=True)
def survey_command(paths, jobs, scheduler, states, seed, timeout, quiet, output_format) -> None:
    """Check every model file among PATH... (files, or folders searched recursively for .urdf and .xml
    files whose root is <robot> or <mujoco>; pybullet_data:<path> for PyBullet's, pybullet_data: for all of
    them), each as `xval model check` does, one row per file: agrees,
    disagrees (engines and cause), refused (the reason), crashed (engine and signal). Exit code 0 when
    nothing crashed, 1 when something did, 2 for bad input."""
    from compare.model.survey import counts, find_models, survey

    models = find_models(paths)
    progress = _survey_progress(len(models), quiet)
    try:
        rows = survey(models, states=states, seed=seed, timeout=timeout, jobs=jobs, scheduler=scheduler,
                      advance=progress.advance)
    finally:
        progress.stop()
    totals = counts(rows)
    if output_format == "json":
        click.echo(json.dumps({"files": [row.to_dict() for row in rows], "counts": totals, "states": states,
                               "seed": seed, "tolerance": TOLERANCE}, indent=1, ensure_ascii=False))
    else:
        click.echo(render_survey(rows, totals))
    raise click.exceptions.Exit(1 if totals["crashed"] or totals["failed"] else 0)


def render_survey(rows, totals: dict[str, int]) -> str:
    header = ["model", "result", "engines", "reason"]
    cells = [[row.model, row.outcome, ", ".join(row.engines) or "-", row.reason or "-"] for row in rows]
    widths = [max(len(r[k]) for r in [header, *cells]) for k in range(3)]
    lines = ["  ".join([*(c.ljust(w) for c, w in zip(r[:3], widths)), r[3]]).rstrip() for r in [header, *cells]]
    lines.append(f"{len(rows)} files: " + ", ".join(f"{count} {outcome}" for outcome, count in totals.items()))
    return "\n".join(lines)


class _SurveyProgress:
    """A rich bar on a terminal, a line at every tenth of the files otherwise (stderr); nothing with --quiet."""

    def __init__(self, total: int, quiet: bool) -> None:
        import sys

        self.total, self.done, self.quiet, self.stream, self.bar = total, 0, quiet, sys.stderr, None
        if not quiet and self.stream.isatty():
            from rich.console import Console
            from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

            self.bar = Progress(TextColumn("checking"), BarColumn(), MofNCompleteColumn(), TimeRemainingColumn(),
                                TextColumn("{task.fields[last]}", style="dim"),
                                console=Console(file=self.stream), transient=True)
            self.bar.start()
            self.task = self.bar.add_task("files", total=total, last="")

    def advance(self, row) -> None:
        before, self.done = self.done, self.done + 1
        if self.bar is not None:
            self.bar.update(self.task, advance=1, last=f"{row.model}: {row.outcome}"[-60:])
        elif not self.quiet and self.total and self.done * 10 // self.total > before * 10 // self.total:
            click.echo(f"checking: {self.done}/{self.total} files", err=True)

    def stop(self) -> None:
        if self.bar is not None:
            self.bar.stop()


def _survey_progress(total: int, quiet: bool) -> _SurveyProgress:
    return _SurveyProgress(total, quiet)
