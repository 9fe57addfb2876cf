"""``xval stability``: the stability search over a suite's scenes × engine variants, then its Baumgarte gain map."""

from __future__ import annotations

import sys

import click

from compare.cli import jobs_option, output_path, timeout_option

from compare.stability.gainmap import plan_gainmap, run_gainmap
from compare.stability.search import BOUNDED, STABLE_AT_LARGEST, UNDECIDED, UNSTABLE_AT_SMALLEST, PairResult, plan_stability, run_stability
from compare.stability.trial import RETRY_FACTOR
from compare.suite.reader import load_suite


def describe(result: PairResult) -> str:
    """One line per pair: ``bead · ours/baumgarte-euler: largest stable dt 0.0019 s (unstable at 0.0021 s)``."""
    head = f"{result.scene_id} · {result.engine}: "
    if result.verdict == BOUNDED:
        text = f"largest stable dt {result.largest_stable_dt:.3g} s (unstable at {result.smallest_unstable_dt:.3g} s)"
    elif result.verdict == STABLE_AT_LARGEST:
        text = f"stable at the largest dt tried, {result.largest_stable_dt:.3g} s"
    elif result.verdict == UNSTABLE_AT_SMALLEST:
        text = f"UNSTABLE even at the smallest dt tried, {result.smallest_unstable_dt:.3g} s"
    elif result.verdict == UNDECIDED:
        text = (f"undecided: the trial at {result.undecided_dt:.3g} s timed out twice (stable at "
                f"{_or_none(result.largest_stable_dt)}, unstable at {_or_none(result.smallest_unstable_dt)}); "
                f"raise --timeout")
    else:
        text = f"skipped ({result.reason})"
    if result.analytic_dt is not None:
        text += f"; theory {result.analytic_dt:.3g} s"
    return head + text


def _or_none(dt: float | None) -> str:
    return "none tried" if dt is None else f"{dt:.3g} s"


@click.command("stability")
@click.argument("suite_path", metavar="SUITE")
@click.option("--output", required=True, metavar="DIR", callback=output_path,
              help="Directory for stability.json and gainmap.json (created; may hold an 'xval run' of the suite).")
@jobs_option("Pairs searched at once")
@timeout_option(help=f"Seconds per trial run before it is killed and run again with {RETRY_FACTOR:g}x the limit; a "
                   "second timeout leaves the boundary undecided, never unstable (default: the suite's).")
@click.option("--force", is_flag=True, help="Replace stability.json / gainmap.json already in DIR.")
@click.option("--search/--no-search", default=True, help="Run the stability search (default: yes).")
@click.option("--gain-map/--no-gain-map", "gain_map", default=True,
              help="Run the suite's [gainmap] Baumgarte gain map, when it has one (default: yes).")
def command(suite_path, output, jobs, timeout, force, search, gain_map) -> None:
    """Find, per scene x engine variant of SUITE, the largest dt at which a run stays ok.

    Stable means: every sample delivered over the scene's duration with a
    finite state, energy drift and constraint error under the suite's
    [bounds]. The search steps dt down from dt_max by sqrt(10) until a run is
    stable, then bisects on a log scale to 10 % in dt. The suite's optional
    [stability] table picks scenes, engines and the dt range; its [gainmap]
    table runs ours/baumgarte over a k_s x k_d grid. Exit 0 when the search
    completed, 2 for bad input.
    """
    suite = load_suite(suite_path)
    # Validate both plans before any trial runs, so a typo costs nothing.
    plan_stability(suite)
    gain_plan = plan_gainmap(suite) if gain_map else None
    if search:
        path = run_stability(suite, output, jobs=jobs, timeout=timeout, force=force,
                             on_pair=lambda r: click.echo(describe(r), err=True))
        click.echo(f"stability: {path}")
    if gain_plan is not None:
        def progress(done: int, total: int) -> None:
            if done % 100 == 0 or done == total:
                print(f"gain map: {done}/{total} cells", file=sys.stderr, flush=True)

        gain_path = run_gainmap(suite, output, jobs=jobs, timeout=timeout, force=force, on_cell=progress)
        click.echo(f"gain map: {gain_path}")
