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

Then, for pymunk's defaults against error_bias = 0: the signed energy change
of the bead over 100 s, the bead's period error, the tension error against
the reference, and the chain of 16 at large steps.

The numbers quoted in docs/engines.md ("## pymunk") come from this script:

    .venv/bin/python scripts/defaults_pymunk.py
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from quoted import Case, Row, load_quotes, report  # noqa: E402

from compare.results.metrics import constraint_error, energy_drift, energy_drift_series, position_error  # noqa: E402
from engines.scene import catalog
from engines.reference.closed_form import pendulum_period
from engines.pymunk.adapter import ENGINE, PYMUNK_DAMPING, PYMUNK_ERROR_BIAS, PYMUNK_ITERATIONS
from engines.reference.reference import solve
from engines.scene.trajectory import tensions

#: Horizon (s) of the position-error column.
ERROR_HORIZON = 1.0


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


def table_head(title: str, *columns: str) -> list[str]:
    """The Markdown lines that open one table of this script's output: its heading and header rows."""
    return [f"### {title}", "", "| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]


def table(case: Case, rows) -> str:
    lines = table_head(
        case.label,
        "setting", "status", "constraint error (m)", "energy drift (E*)", "position error, first 1 s (m)", "cost (s/s)",
    )
    for label, status, c_err, drift, p_err, cost in rows:
        lines.append(f"| {label} | {status} | {c_err:.2g} | {drift:.2g} | {p_err:.2g} | {cost:.2g} |")
    return "\n".join(lines)


def long_run_energy() -> str:
    """Signed energy change of the 60° bead over 100 s: is the default bias's loss steady?"""
    scene = catalog.build("bead", {"duration": 100.0})
    lines = table_head(
        "bead, 60°, 100 s, dt = 1e-3: signed energy change (E − E(0)) / E*",
        "setting", "at 10 s", "at 100 s", "max abs over 100 s",
    )
    for label, options in SETTINGS[:2]:
        run = ENGINE.simulate(scene, 1e-3, variant="pin", options=options)
        series = energy_drift_series(scene, run.positions, run.velocities)
        at_10 = series[int(np.argmin(np.abs(run.t - 10.0)))]
        lines.append(f"| {label} | {at_10:.2g} | {series[-1]:.2g} | {np.abs(series).max():.2g} |")
    return "\n".join(lines)


def bead_period() -> str:
    """Relative period error of the 10° bead at dt = 1e-3 (zero crossings of x, sampled every step)."""
    dt, theta0 = 1e-3, math.radians(10.0)
    exact = pendulum_period(1.0, 9.81, theta0)
    scene = catalog.build("bead", {"theta0": 10.0, "duration": 4 * exact})
    lines = table_head(
        "bead, 10°, dt = 1e-3: period against the elliptic-integral period",
        "setting", "relative period error",
    )
    for label, options in SETTINGS[:2]:
        run = ENGINE.simulate(scene, dt, variant="pin", options=options, sample_interval=dt)
        x = run.positions[:, 0, 0]
        i = np.nonzero(np.signbit(x[1:]) != np.signbit(x[:-1]))[0]
        crossings = run.t[i] - x[i] * dt / (x[i + 1] - x[i])
        period = 2 * np.polyfit(np.arange(len(crossings)), crossings, 1)[0]
        lines.append(f"| {label} | {(period - exact) / exact:.2g} |")
    return "\n".join(lines)


def tension_error() -> str:
    """Largest |T − T_ref| (N) on the 60° bead over 1 s (the whole tension range) at dt = 1e-3."""
    scene = catalog.build("bead", {"duration": 1.0})
    reference = solve(scene)
    lines = table_head(
        "bead, 60°, 1 s, dt = 1e-3: tension from impulse / dt against the reference",
        "setting", "max tension error (N)", "reference tension range (N)",
    )
    for label, options in SETTINGS[:2]:
        run = ENGINE.simulate(scene, 1e-3, variant="pin", options=options)
        positions, _, forces = reference.at(run.t)
        expected = tensions(scene, positions, forces)[1:, 0]
        measured = tensions(scene, run.positions, run.constraint_forces)[1:, 0]
        lines.append(
            f"| {label} | {np.abs(measured - expected).max():.2g} | {expected.min():.3g}–{expected.max():.3g} |"
        )
    return "\n".join(lines)


def large_steps() -> str:
    """Status and largest speed of the chain of 16 at large steps: does pymunk blow up?"""
    case = CASES[-1]
    scene = catalog.build(case.scene, {**case.parameters, "duration": 5.0})
    lines = table_head(
        "chain of 16, 5 s, large steps: status and largest speed",
        "setting", "dt (s)", "status", "max speed (m/s)", "energy drift (E*)",
    )
    for label, options in (SETTINGS[0], SETTINGS[4]):
        for dt in (0.02, 0.05, 0.1):
            run = ENGINE.simulate(scene, dt, variant="pin", options=options)
            speed = np.linalg.norm(run.velocities, axis=2).max() if run.n_samples else math.nan
            drift = energy_drift(scene, run.positions, run.velocities)
            lines.append(f"| {label} | {dt:g} | {run.info.status} | {speed:.3g} | {drift:.2g} |")
    return "\n".join(lines)


SLOW_CASES = {"chain4", "chain16", "large"}  # key prefixes left out of a quick run (see figures)


def figures(quick: bool = False) -> dict[str, float]:
    """Every quoted figure. Keys: ``<case>|<setting>|cerr|drift|perr``, and named ones below."""
    f: dict[str, float] = {}
    tags = ("bead", "bead60Hz", "double", "chain4", "chain16")
    settings = {SETTINGS[0][0]: "defaults", "error_bias = 0": "bias0", "error_bias = 0, iterations = 3": "bias0_iter3",
                "error_bias = 0, iterations = 50": "bias0_iter50", "damping = 0.999 (not a default)": "damping0.999"}
    for tag, case in zip(tags, CASES):
        if quick and tag in SLOW_CASES:
            continue
        for label, _status, c_err, drift, p_err, _cost in measure(case):
            if label in settings:
                for name, value in (("cerr", c_err), ("drift", drift), ("perr", p_err)):
                    f[f"{tag}|{settings[label]}|{name}"] = float(value)
    # 100 s of the 60° bead: the signed energy change.
    scene = catalog.build("bead", {"duration": 100.0})
    for label, options in SETTINGS[:2]:
        run = ENGINE.simulate(scene, 1e-3, variant="pin", options=options)
        series = energy_drift_series(scene, run.positions, run.velocities)
        key = settings[label]
        f[f"long|{key}|loss_10s"] = -float(series[int(np.argmin(np.abs(run.t - 10.0)))])
        f[f"long|{key}|loss_100s"] = -float(series[-1])
        f[f"long|{key}|max_abs"] = float(np.abs(series).max())
    # The 10° bead's period.
    dt, theta0 = 1e-3, math.radians(10.0)
    exact = pendulum_period(1.0, 9.81, theta0)
    scene = catalog.build("bead", {"theta0": 10.0, "duration": 4 * exact})
    for label, options in SETTINGS[:2]:
        run = ENGINE.simulate(scene, dt, variant="pin", options=options, sample_interval=dt)
        x = run.positions[:, 0, 0]
        i = np.nonzero(np.signbit(x[1:]) != np.signbit(x[:-1]))[0]
        crossings = run.t[i] - x[i] * dt / (x[i + 1] - x[i])
        f[f"period|{settings[label]}"] = float((2 * np.polyfit(np.arange(len(crossings)), crossings, 1)[0] - exact) / exact)
    # Tension from impulse / dt on the 60° bead over 1 s.
    scene = catalog.build("bead", {"duration": 1.0})
    reference = solve(scene)
    for label, options in SETTINGS[:2]:
        run = ENGINE.simulate(scene, 1e-3, variant="pin", options=options)
        positions, _, forces = reference.at(run.t)
        expected = tensions(scene, positions, forces)[1:, 0]
        measured = tensions(scene, run.positions, run.constraint_forces)[1:, 0]
        f[f"tension|{settings[label]}"] = float(np.abs(measured - expected).max())
        f["tension|min"], f["tension|max"] = float(expected.min()), float(expected.max())
    if not quick:
        case = CASES[-1]
        scene = catalog.build(case.scene, {**case.parameters, "duration": 5.0})
        for label, options in (SETTINGS[0], SETTINGS[4]):
            run = ENGINE.simulate(scene, 0.1, variant="pin", options=options)
            f[f"large|{settings[label]}|ok"] = float(run.info.status == "ok")
            f[f"large|{settings[label]}|speed"] = float(np.linalg.norm(run.velocities, axis=2).max())
            f[f"large|{settings[label]}|drift"] = energy_drift(scene, run.positions, run.velocities)
    return f


D = "docs/engines.md"
T = "**Remaining softness, and what each default costs.**"


def _row(label: str, tag: str, setting: str, after: str = T) -> Row:
    return Row(D, label, tuple(f"{tag}|{setting}|{c}" for c in ("cerr", "drift", "perr")), after)


ROWS = [
    _row("bead 60°, 10 s | defaults", "bead", "defaults"),
    _row("| error_bias = 0", "bead", "bias0", "| bead 60°, 10 s | defaults"),
    _row("double pendulum, 10 s | defaults", "double", "defaults"),
    _row("| error_bias = 0", "double", "bias0", "| double pendulum, 10 s | defaults"),
    _row("chain of 4, 5 s | defaults", "chain4", "defaults"),
    _row("| error_bias = 0", "chain4", "bias0", "| chain of 4, 5 s | defaults"),
    _row("| error_bias = 0, 3 iterations", "chain4", "bias0_iter3", "| chain of 4, 5 s | defaults"),
    _row("chain of 16, 3 s | defaults", "chain16", "defaults"),
    _row("| error_bias = 0 (10 iterations)", "chain16", "bias0", "| chain of 16, 3 s | defaults"),
    _row("| error_bias = 0, 50 iterations", "chain16", "bias0_iter50", "| chain of 16, 3 s | defaults"),
]
QUOTES = load_quotes(__file__)
SLOW = {k for r in ROWS for k in r.keys if k.split("|")[0] in SLOW_CASES} | {
    q.key for q in QUOTES if q.key.split("|")[0] in SLOW_CASES}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", type=int, action="append", help="index of a case to run (default: all)")
    args = parser.parse_args(argv)
    chosen = [CASES[i] for i in args.case] if args.case else list(CASES)
    print(f"pymunk {ENGINE.version()}\n")
    for case in chosen:
        print(table(case, measure(case)))
        print()
    if not args.case:
        for section in (long_run_energy, bead_period, tension_error, large_steps):
            print(section())
            print()
        report(figures(), QUOTES, ROWS)
    return 0


if __name__ == "__main__":
    sys.exit(main())
