"""``xval run``: run a suite into a results directory, then print the verdict (and, with --verbose, the tables)."""

from __future__ import annotations

import sys

import click

from compare.run import startup

startup.load_blas_single_threaded()  # first, before anything imports numpy (why: compare/run/startup.py)

from engines.errors import UserError  # noqa: E402

from compare.cli import MemorySize, history_option, jobs_option, output_path, timeout_option  # noqa: E402
from compare.run.isolation import DEFAULT_MEMORY_LIMIT  # noqa: E402

from compare.results.table import scene_tables  # noqa: E402
from compare.results.verdict import scene_verdicts  # noqa: E402
from compare.results.verdict_format import format_verdicts  # noqa: E402
from compare.run.progress import progress_for  # noqa: E402
from compare.run.runner import run_suite  # noqa: E402
from compare.suite.reader import load_suite  # noqa: E402


@click.command("run")
@click.argument("suite_path", metavar="SUITE")
@click.option("--output", required=True, metavar="DIR", callback=output_path,
              help="Results directory to create (or finish, with --resume).")
@jobs_option("Cases run at once (case host processes)")
@click.option("--resume", is_flag=True, help="Run only the cases DIR does not hold yet.")
@timeout_option(help="Seconds per case (and per scene's reference solve) before it is killed and recorded as "
                   "timeout, at most 1e6 (default: the suite's).")
@click.option("--memory-limit", type=MemorySize(), default=f"{DEFAULT_MEMORY_LIMIT // 2**30}G", metavar="SIZE",
              show_default=True,
              help="Memory (address space) each case may add to its process's own, at least 256M, or "
                   "'none'. A case past it is recorded failed with the reason.")
@click.option("--scheduler", default=None, metavar="tcp://HOST:PORT|local[:N]",
              help="Run the cases on a Dask cluster: a scheduler's address, or local[:N] for an "
                   "in-process cluster of N workers (needs: pip install 'xval[dask]').")
@click.option("--quiet", "-q", is_flag=True, help="No progress while running; at the end only the verdict and the problems.")
@click.option("--verbose", "-v", is_flag=True, help="A line per case while running, and every scene's table at the end.")
@history_option(name="history", help="Also append the finished run to this history (xval history; a SQLite file or a postgresql:// URL).")
def command(suite_path, output, jobs, resume, timeout, memory_limit, scheduler, quiet, verbose, history) -> None:
    """Run every scene x engine variant x dt of SUITE (a TOML file) and record each case in DIR.

    While it runs: one progress bar (a line at every tenth of the run when
    the output is not a terminal). At the end, per scene: the most accurate
    variant of each engine at equal cost, how the suite's first engine family
    compares with the best other one, and the problems (inconsistent,
    failed, timed out, unstable — with the dts). A case that fails, goes
    unstable or times out is recorded with its status and does not stop the
    others. Exit code 0 when the run completed (whatever the cases'
    statuses), 2 for bad input, 1 when the Dask scheduler was lost (finished
    cases are kept; --resume finishes the run).
    """
    if quiet and verbose:
        raise UserError("--quiet and --verbose: choose one (--quiet prints only the verdict, --verbose a line per case)")
    mode = "quiet" if quiet else "verbose" if verbose else "bar"
    # No collection while the suite loads its engines, until runner.preload_engines has frozen them
    # (why: compare/run/startup.py); back on in any case once the run is over.
    startup.defer_collection()
    try:
        summary = _run(suite_path, output, jobs, resume, timeout, memory_limit, scheduler, mode)
    finally:
        startup.resume_collection()
    # The run's records as the results directory holds them, judged once: for the verdict and the history.
    results = summary.results()
    variant_sweeps = results.sweeps()
    if verbose:
        click.echo(scene_tables(variant_sweeps), nl=False)
        click.echo()
    verdicts = scene_verdicts(variant_sweeps)
    click.echo(format_verdicts(verdicts), nl=False)
    counts = ", ".join(f"{n} {status}" for status, n in summary.counts.items())
    resumed = f", {summary.already_done} already done" if summary.already_done else ""
    click.echo(f"\n{summary.ran} cases run in {summary.wall_time:.1f} s{resumed} ({counts})")
    click.echo(f"results: {summary.path}")
    if not quiet and not verbose:
        click.echo(f"tables: xval show {summary.path}; report: xval report {summary.path}")
    if history is not None:
        from compare.commands.history import add_results

        click.echo(add_results(results, history, suite_path=suite_path))


def _run(suite_path, output, jobs, resume, timeout, memory_limit, scheduler, mode):
    """The RunSummary of the suite's run, run here or on a Dask cluster."""
    suite = load_suite(suite_path)
    if scheduler is None:
        return run_suite(suite, output, jobs=jobs, resume=resume, timeout=timeout,
                         progress=progress_for(sys.stderr, mode), memory_limit=memory_limit)
    from compare.run.cluster import SchedulerLost, run_on_cluster  # dask is imported only when asked for

    try:
        return run_on_cluster(suite, output, scheduler, jobs=jobs, resume=resume, timeout=timeout,
                              memory_limit=memory_limit, progress=progress_for(sys.stderr, mode),
                              warn=lambda line: click.echo(f"xval: warning: {line}", err=True))
    except SchedulerLost as exc:
        click.echo(f"xval: error: {exc}; the finished cases are in {output}: run again with --resume", err=True)
        sys.exit(1)
