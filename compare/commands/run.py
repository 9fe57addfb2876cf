"""``xval run``: run a suite into a results directory, then print a table per scene."""

from __future__ import annotations

import sys

import click

from engines.limits import MAX_JOBS

from compare.cli import MemorySize, Seconds, output_path
from compare.run.isolation import DEFAULT_MEMORY_LIMIT
from compare.run.progress import progress_for
from compare.run.runner import run_suite
from compare.suite.reader import load_suite
from compare.results.table import scene_tables


@click.command("run")
@click.argument("suite_path", metavar="SUITE")
@click.option("--output", required=True, metavar="DIR", callback=output_path,
              help="Results directory to create (or finish, with --resume).")
@click.option("--jobs", type=click.IntRange(min=1, max=MAX_JOBS), default=None,
              help=f"Worker processes, 1 to {MAX_JOBS} (default: all cores).")
@click.option("--resume", is_flag=True, help="Run only the cases DIR does not hold yet.")
@click.option("--timeout", type=Seconds(), default=None, metavar="S",
              help="Seconds per case (and per scene's reference solve) before it is killed and recorded as "
                   "timeout, at most 1e6 (default: the suite's).")
@click.option("--memory-limit", type=MemorySize(), default=f"{DEFAULT_MEMORY_LIMIT // 2**30}G", metavar="SIZE",
              show_default=True,
              help="Memory (address space) each case may add to its process's own, at least 256M, or "
                   "'none'. A case past it is recorded failed with the reason.")
@click.option("--scheduler", default=None, metavar="tcp://HOST:PORT|local[:N]",
              help="Run the cases on a Dask cluster: a scheduler's address, or local[:N] for an "
                   "in-process cluster of N workers (needs: pip install 'xval[dask]').")
def command(suite_path, output, jobs, resume, timeout, memory_limit, scheduler) -> None:
    """Run every scene x engine variant x dt of SUITE (a TOML file) and record each case in DIR.

    A case that fails, goes unstable or times out is recorded with its status
    and does not stop the others. Exit code 0 when the run completed (whatever
    the cases' statuses), 2 for bad input, 1 when the Dask scheduler was lost
    (finished cases are kept; --resume finishes the run).
    """
    suite = load_suite(suite_path)
    if scheduler is None:
        summary = run_suite(suite, output, jobs=jobs, resume=resume, timeout=timeout, progress=progress_for(sys.stderr),
                            memory_limit=memory_limit)
    else:
        from compare.run.cluster import SchedulerLost, run_on_cluster  # dask is imported only when asked for

        try:
            summary = run_on_cluster(suite, output, scheduler, jobs=jobs, resume=resume, timeout=timeout,
                                     memory_limit=memory_limit,
                                     progress=progress_for(sys.stderr),
                                     warn=lambda line: click.echo(f"xval: warning: {line}", err=True))
        except SchedulerLost as exc:
            click.echo(f"xval: error: {exc}; the finished cases are in {output}: run again with --resume", err=True)
            sys.exit(1)
    click.echo(scene_tables(summary.records, suite.verdict_tolerance), nl=False)
    counts = ", ".join(f"{n} {status}" for status, n in summary.counts.items())
    resumed = f", {summary.already_done} already done" if summary.already_done else ""
    click.echo(f"\n{summary.ran} cases run in {summary.wall_time:.1f} s{resumed} ({counts})")
    click.echo(f"results: {summary.path}")
