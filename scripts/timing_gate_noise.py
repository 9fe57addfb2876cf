"""Does the timing gate tell a busy neighbour from a regression? (docs/reliability.md quotes this.)

1. Runs a small suite (2 scenes x 2 engines, repeats = 3, timing_factor = 1.5)
   once and makes it the baseline.
2. Starts one busy-loop process (the "neighbour", bounded: it exits by itself
   after LOAD_SECONDS and is killed by pid at the end) and reruns the same
   suite RERUNS times, gating each rerun against the baseline twice: with the
   CPU-time rule (what ``xval gate`` does) and with the older wall-time rule
   (the same entries with their CPU times removed).
3. Reruns once with every stepping loop done twice (XVAL_SLOWDOWN=2, see
   scripts/slowed_engines.py) and gates that.

Prints the false failures of each rule over the reruns, and the verdict on
the 2x slowdown. Usage: python scripts/timing_gate_noise.py [RERUNS]
"""

from __future__ import annotations

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

SUITE = """name = "timing-noise"
dt = [2e-4]
duration = 2.0
repeats = 3
engines = ["slowed_engines:MUJOCO/hinge", "slowed_engines:PYMUNK/pin"]
[gate]
timing_factor = 1.5
[[scenes]]
scene = "bead"
[[scenes]]
scene = "double-pendulum"
"""
RERUNS = int(sys.argv[1]) if len(sys.argv) > 1 else 20
#: s: the neighbour stops by itself after this, even if this script dies.
LOAD_SECONDS = 900
LOAD = f"import time\nend = time.monotonic() + {LOAD_SECONDS}\nwhile time.monotonic() < end: pass\n"


def without_cpu(baseline: Baseline) -> Baseline:
    """The baseline with the CPU timings removed: what the wall-time rule sees."""
    cases = {key: replace(entry, timing=entry.timing and replace(entry.timing, cpu=None, calibration=None))
             for key, entry in baseline.cases.items()}
    return replace(baseline, cases=cases)


def slow_rows(report) -> list[str]:
    return [f"{c.scene_id} {c.engine}: {ch.note}" for c in report.cases for ch in c.changes
            if ch.metric == "cost_per_simulated_second" and ch.outcome == "worse" and ch.gated]


def main() -> None:
    suite = parse_suite(SUITE, "timing-noise.toml")
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)

        def rerun(name: str):
            run_suite(suite, root / name, jobs=1)
            return build_baseline(load_results(root / name))

        baseline = rerun("baseline")
        settings = suite.gate
        neighbour = subprocess.Popen([sys.executable, "-c", LOAD])
        try:
            cpu_failures, wall_failures, worst = 0, 0, []
            started = time.monotonic()
            for k in range(RERUNS):
                current = rerun(f"rerun-{k}")
                report = gate_results(baseline, current, settings, "baseline")
                wall = gate_results(without_cpu(baseline), without_cpu(current), settings, "baseline")
                cpu_failures += not report.passed
                wall_failures += not wall.passed
                worst += slow_rows(wall)
                print(f"rerun {k + 1:2d}: cpu rule {'FAIL' if not report.passed else 'pass'}, "
                      f"wall rule {'FAIL' if not wall.passed else 'pass'}", flush=True)
            print(f"{RERUNS} reruns of an unchanged build in {time.monotonic() - started:.0f} s with a busy-loop "
                  f"neighbour: {cpu_failures} false failures with the CPU-time rule, {wall_failures} with the "
                  f"wall-time rule")
            for row in worst[:5]:
                print(f"  wall rule flagged: {row}")
            os.environ["XVAL_SLOWDOWN"] = "2"
            slowed = gate_results(baseline, rerun("slowed"), settings, "baseline")
            os.environ.pop("XVAL_SLOWDOWN")
            caught = slow_rows(slowed)
            print(f"2x slowdown: gate {'FAILED' if not slowed.passed else 'passed'}, "
                  f"{len(caught)} of {len(slowed.cases)} cases caught")
            for row in caught:
                print(f"  {row}")
        finally:
            neighbour.kill()
            neighbour.wait()


if __name__ == "__main__":
    main()
