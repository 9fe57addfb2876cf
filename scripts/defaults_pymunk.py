"""Measure what each pymunk default costs in accuracy: error_bias, iterations, damping.

For a few catalog scenes, runs the pymunk adapter with pymunk's own solver
defaults and with one default changed at a time, and prints a Markdown table
per scene:

- constraint error: max |‖a − b‖ − l| over constraints and samples, m;
- energy drift: max |E(t) − E(0)| / E*, E* = total mass · g · L;
- position error: max over the first second of e(t) = max over particles of
  the distance to the reference (DOP853, rtol = atol = 1e-12), m (one second
  only: the double pendulum and the chain are chaotic, so later errors
  measure chaos rather than the solver);
- cost: stepping wall time per simulated second, s/s.

The numbers quoted in docs/engines.md ("## pymunk") come from this script:

    .venv/bin/python scripts/defaults_pymunk.py
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass
from typing import Any, Mapping

from compare.metrics import constraint_error, energy_drift, position_error
from engines import catalog
from engines.pymunk import ENGINE, PYMUNK_DAMPING, PYMUNK_ERROR_BIAS, PYMUNK_ITERATIONS
from engines.reference import solve

#: Horizon (s) of the position-error column.
ERROR_HORIZON = 1.0


@dataclass(frozen=True)
class Case:
    """A scene and a time step to measure the settings on."""

    label: str
    scene: str
    parameters: Mapping[str, Any]
    dt: float


CASES = (
    Case("bead, 60°, 10 s, dt = 1e-3", "bead", {"duration": 10.0}, 1e-3),
    # pymunk's default error_bias is phrased per 1/60 s: the game step it was tuned for.
    Case("bead, 60°, 10 s, dt = 1/60", "bead", {"duration": 10.0}, 1.0 / 60.0),
    Case("double pendulum (120°, −10°), 10 s, dt = 1e-3", "double-pendulum", {"duration": 10.0}, 1e-3),
    Case("chain of 4, 5 s, dt = 1e-3", "chain", {"duration": 5.0}, 1e-3),
    Case(
        "chain of 16 (1 m, 1 kg in all), 3 s, dt = 1e-3",
        "chain",
        {"n": 16, "length": 1 / 16, "mass": 1 / 16, "duration": 3.0},
        1e-3,
    ),
)

#: (label, options on top of pymunk's defaults). The first row leaves every default in place.
SETTINGS = (
    (f"pymunk defaults (error_bias {PYMUNK_ERROR_BIAS:.4g}, {PYMUNK_ITERATIONS} iterations, damping {PYMUNK_DAMPING:g})", {}),
    ("error_bias = 0", {"error_bias": 0.0}),
    ("iterations = 3", {"iterations": 3}),
    ("iterations = 50", {"iterations": 50}),
    ("error_bias = 0, iterations = 3", {"error_bias": 0.0, "iterations": 3}),
    ("error_bias = 0, iterations = 50", {"error_bias": 0.0, "iterations": 50}),
    # Not a default: pymunk's damping default is 1 (none). This row shows what a
    # damping below 1 would do, which the energy-drift tests must catch.
    ("damping = 0.999 (not a default)", {"damping": 0.999}),
)


def measure(case: Case) -> list[tuple[str, str, float, float, float, float]]:
    """One row per setting: (label, status, constraint error m, energy drift, position error m, s per simulated s)."""
    scene = catalog.build(case.scene, case.parameters)
    reference = solve(scene)
    rows = []
    for label, options in SETTINGS:
        run = ENGINE.simulate(scene, case.dt, variant="pin", options=options)
        early = run.t <= ERROR_HORIZON + 1e-12
        reference_positions, _, _ = reference.at(run.t[early])
        error = position_error(run.positions[early], reference_positions)
        rows.append(
            (
                label,
                run.info.status,
                constraint_error(scene, run.positions),
                energy_drift(scene, run.positions, run.velocities),
                float(error.max()) if len(error) else math.nan,
                run.info.wall_time / scene.duration,
            )
        )
    return rows


def table(case: Case, rows) -> str:
    lines = [
        f"### {case.label}",
        "",
        "| setting | status | constraint error (m) | energy drift (E*) | position error, first 1 s (m) | cost (s/s) |",
        "|---|---|---|---|---|---|",
    ]
    for label, status, c_err, drift, p_err, cost in rows:
        lines.append(f"| {label} | {status} | {c_err:.2g} | {drift:.2g} | {p_err:.2g} | {cost:.2g} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", type=int, action="append", help="index of a case to run (default: all)")
    args = parser.parse_args(argv)
    chosen = [CASES[i] for i in args.case] if args.case else list(CASES)
    print(f"pymunk {ENGINE.version()}\n")
    for case in chosen:
        print(table(case, measure(case)))
        print()
    return 0


if __name__ == "__main__":
    sys.exit(main())
