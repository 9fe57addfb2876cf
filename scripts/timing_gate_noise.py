"""Does the timing gate tell a busy neighbour from a regression? (docs/reliability.md quotes this.)

1. Runs a small suite (2 scenes x 2 engines, dt 2e-4 s for 20 s, repeats = 3, timing_factor = 1.5)
   once and makes it the baseline. Each case steps 1e5 times, so that its stepping lasts longer than the
   gate's resolution (compare.gate.gate.CASE_RESOLUTION) and it is gated on its own (the shortest,
   pymunk's bead, steps ~70 ms of CPU on the 2-core machine the doc's figures come from; on a machine
   fast enough to take it below, it is judged by its variant's two cases together, still gated).
2. Starts busy-loop neighbours, PER_CORE per core (each bounded: it exits by itself after LOAD_SECONDS
   and is killed by pid at the end), and reruns the same suite RERUNS times, gating each rerun against
   the baseline twice: with the CPU-time rule (what ``xval gate`` does) and with the older wall-time
   rule (the same entries with their CPU times removed).
3. Reruns once with every run's CPU doubled (XVAL_SLOWDOWN=2, scripts/slowed_engines.py: a busy loop
   in the run's thread for as much CPU time again) and gates that.

Prints the false failures of each rule over the reruns, and the verdict on the 2x slowdown; then
:func:`quoted.report`. Usage: python scripts/timing_gate_noise.py [--reruns N] [--per-core K]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

from compare.gate.baseline import Baseline, build_baseline  # noqa: E402
from compare.gate.gate import gate_results  # noqa: E402
from compare.run.results import load_results  # noqa: E402
from compare.run.runner import run_suite  # noqa: E402
from compare.suite.reader import parse_suite  # noqa: E402
from quoted import load_quotes, report  # noqa: E402

SUITE = """name = "timing-noise"
dt = [2e-4]
duration = 20.0
repeats = 3
engines = ["slowed_engines:MUJOCO/hinge", "slowed_engines:PYMUNK/pin"]
[gate]
timing_factor = 1.5
[[scenes]]
scene = "bead"
[[scenes]]
scene = "double-pendulum"
"""
RERUNS = 20
#: Busy-loop neighbours per core: two, so that the suite's thread gets about a third of a core on any
#: machine (one neighbour on a machine with idle cores would load nothing).
PER_CORE = 2
#: s: the neighbour stops by itself after this, even if this script dies.
LOAD_SECONDS = 1800
LOAD = f"import time\nend = time.monotonic() + {LOAD_SECONDS}\nwhile time.monotonic() < end: pass\n"


def without_cpu(baseline: Baseline) -> Baseline:
    """The baseline with the CPU timings removed: what the wall-time rule sees."""
    cases = {key: replace(entry, timing=entry.timing and replace(entry.timing, cpu=None, calibration=None))
             for key, entry in baseline.cases.items()}
    return replace(baseline, cases=cases)


def slow_rows(report, gated: bool = True) -> list[str]:
    """The cases ``report`` found slower, gated (or, with ``gated`` False, those shown and not gated)."""
    return [f"{c.scene_id} {c.engine}: {ch.note}" for c in report.cases for ch in c.changes
            if ch.metric == "cost_per_simulated_second" and ch.outcome == "worse" and ch.gated == gated]


def measure(reruns: int = RERUNS, per_core: int = PER_CORE) -> dict[str, float]:
    """The counts of steps 2 and 3 of the module's docstring, printed as they come."""
    suite = parse_suite(SUITE, "timing-noise.toml")
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)

        def rerun(name: str):
            run_suite(suite, root / name, jobs=1)
            return build_baseline(load_results(root / name))

        baseline = rerun("baseline")
        settings = suite.gate
        neighbours = [subprocess.Popen([sys.executable, "-c", LOAD]) for _ in range(per_core * (os.cpu_count() or 1))]
        try:
            cpu_failures, wall_failures, worst = 0, 0, []
            started = time.monotonic()
            for k in range(reruns):
                current = rerun(f"rerun-{k}")
                report = gate_results(baseline, current, settings, "baseline")
                wall = gate_results(without_cpu(baseline), without_cpu(current), settings, "baseline")
                cpu_failures += not report.passed
                wall_failures += not wall.passed
                worst += slow_rows(wall)
                print(f"rerun {k + 1:2d}: cpu rule {'FAIL' if not report.passed else 'pass'}, "
                      f"wall rule {'FAIL' if not wall.passed else 'pass'}", flush=True)
            print(f"{reruns} reruns of an unchanged build with {len(neighbours)} busy loops ({per_core} per core; load "
                  f"average {os.getloadavg()[0]:.1f} at the end, {time.monotonic() - started:.0f} s): {cpu_failures} "
                  f"false failures with the CPU-time rule, {wall_failures} with the wall-time rule")
            for row in worst[:5]:
                print(f"  wall rule flagged: {row}")
            os.environ["XVAL_SLOWDOWN"] = "2"
            try:
                slowed = gate_results(baseline, rerun("slowed"), settings, "baseline")
            finally:
                os.environ.pop("XVAL_SLOWDOWN")
            caught = slow_rows(slowed)
            print(f"2x slowdown: gate {'FAILED' if not slowed.passed else 'passed'}, "
                  f"{len(caught)} of {len(slowed.cases)} cases caught")
            for row in caught:
                print(f"  {row}")
            for row in slow_rows(slowed, gated=False):
                print(f"  shown, not gated: {row}")
        finally:
            for neighbour in neighbours:
                neighbour.kill()
                neighbour.wait()
    return {"false_failures_cpu": float(cpu_failures), "false_failures_wall": float(wall_failures),
            "slowdown_failed": float(not slowed.passed), "slowdown_caught": float(len(caught)),
            "slowdown_cases": float(len(slowed.cases))}


#: Every figure: counts of loaded reruns, minutes of runs (the quote test checks that the doc still quotes them).
SLOW = {"false_failures_cpu", "false_failures_wall", "slowdown_failed", "slowdown_caught", "slowdown_cases"}


def figures(quick: bool = False, reruns: int = RERUNS, per_core: int = PER_CORE) -> dict[str, float]:
    """The counts of :func:`measure`; none when ``quick``."""
    return {} if quick else measure(reruns, per_core)


QUOTES = load_quotes(__file__)
ROWS: list = []


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--reruns", type=int, default=RERUNS)
    parser.add_argument("--per-core", type=int, default=PER_CORE, help="busy-loop neighbours per core")
    args = parser.parse_args()
    found = figures(reruns=args.reruns, per_core=args.per_core)
    if args.reruns == RERUNS and args.per_core == PER_CORE:  # what the doc quotes
        report(found, QUOTES, ROWS)


if __name__ == "__main__":
    main()
