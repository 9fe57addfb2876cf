"""Measure what each PyBullet default costs: damping, motors, sleeping, ERP, solver, iterations, point-mass inertia.

Runs the PyBullet adapter (engines/pybullet/adapter.py) with one default left in
place (or one setting changed) at a time, and prints Markdown tables:

- constraint error: max |‖a − b‖ − l| over constraints and samples, m;
- energy drift: max |E(t) − E(0)| / E*, E* = total mass · g · L;
- swing: peak-to-peak x of the first particle over the last second, m (0
  means it stopped or never moved);
- position error: max over the first second of the distance to the
  reference (DOP853, rtol = atol = 1e-12), m (one second only: the double
  pendulum and the chain are chaotic, later errors measure chaos);
- tension error: max over the first second, t = 0 excluded (the force at
  t = 0 is the first step's, and an iterative solver starts cold), N;
- cost: stepping wall time per simulated second, s/s.

The numbers quoted in docs/engines.md ("## PyBullet") come from this script:

    .venv/bin/python scripts/defaults_pybullet.py
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from quoted import Case, Row, load_quotes, report  # noqa: E402

from compare.results.metrics import constraint_error, energy_drift, position_error  # noqa: E402
from engines.scene import catalog
from engines.pybullet.adapter import ENGINE
from engines.reference.reference import solve
from engines.scene.trajectory import tensions

#: Horizon (s) of the position- and tension-error columns.
ERROR_HORIZON = 1.0


@dataclass(frozen=True)
class Setting:
    """A row: a variant with options on top, and what it changes."""

    label: str
    variant: str
    options: Mapping[str, Any]


BEAD_60 = Case("bead, 60°, 10 s, dt = 1e-3", "bead", {"duration": 10.0}, 1e-3)
BEAD_10 = Case("bead, 10°, 10 s, dt = 1e-3 (slower than the 0.8 m/s sleeping threshold)", "bead", {"theta0": 10.0, "duration": 10.0}, 1e-3)
DOUBLE = Case("double pendulum (120°, −10°), 10 s, dt = 1e-3", "double-pendulum", {"duration": 10.0}, 1e-3)
CHAIN = Case("chain of 4, 5 s, dt = 1e-3", "chain", {"duration": 5.0}, 1e-3)
SPHERICAL = Case("spherical pendulum, 10 s, dt = 1e-3", "spherical-pendulum", {"duration": 10.0}, 1e-3)

#: Table 1: the overrides of engines/pybullet/adapter.py, each switched off in turn.
KEPT_DEFAULTS = (
    Setting("multibody, every override", "multibody", {}),
    Setting("multibody, default damping (0.04) kept", "multibody", {"keep_defaults": "damping"}),
    Setting("multibody, default joint motors kept", "multibody", {"keep_defaults": "motors"}),
    Setting("multibody, default sleeping kept", "multibody", {"keep_defaults": "sleeping"}),
    Setting("p2p-dantzig, every override", "p2p-dantzig", {}),
    Setting("p2p-dantzig, default damping (0.04) kept", "p2p-dantzig", {"keep_defaults": "damping"}),
    Setting("p2p-dantzig, default sleeping kept", "p2p-dantzig", {"keep_defaults": "sleeping"}),
)

#: Table 2: the p2p formulation's solver, iterations and ERP.
SOLVER_SETTINGS = (
    Setting("si, 50 iterations, ERP 0.2 (PyBullet's defaults)", "p2p", {}),
    Setting("si, 500 iterations", "p2p", {"iterations": 500}),
    Setting("pgs (MLCP), 50 iterations", "p2p", {"solver": "pgs"}),
    Setting("dantzig, ERP 0.2", "p2p", {"solver": "dantzig"}),
    Setting("dantzig, ERP 0 (no drift correction)", "p2p", {"solver": "dantzig", "erp": 0.0}),
    Setting("dantzig, ERP 0.8", "p2p", {"solver": "dantzig", "erp": 0.8}),
    Setting("dantzig, ERP 1", "p2p", {"solver": "dantzig", "erp": 1.0}),
    Setting("multibody (no constraint to solve)", "multibody", {}),
)

#: Table 3: the point mass's made-up central inertia, against the solver.
INERTIA_SETTINGS = tuple(
    Setting(f"{solver}, inertia_ratio {ratio:g}", "p2p", {"solver": solver, "inertia_ratio": ratio})
    for solver in ("si", "dantzig")
    for ratio in (1e-2, 1e-4, 1e-6)
)


def measure(case: Case, setting: Setting, reference) -> dict[str, float | str]:
    """One run's row: the metrics described in the module docstring."""
    scene = catalog.build(case.scene, case.parameters)
    run = ENGINE.simulate(scene, case.dt, variant=setting.variant, options=setting.options)
    row: dict[str, float | str] = {"status": run.info.status}
    if run.n_samples == 0:
        return row
    row["constraint error (m)"] = constraint_error(scene, run.positions)
    row["energy drift"] = energy_drift(scene, run.positions, run.velocities)
    last_second = run.t >= run.t[-1] - 1.0
    row["swing (m)"] = float(np.ptp(run.positions[last_second, 0, 0]))
    early = run.t <= ERROR_HORIZON
    positions, _, forces = reference.at(run.t[early])
    row["position error (m)"] = float(position_error(run.positions[early], positions).max())
    if run.constraint_forces is not None:
        measured = tensions(scene, run.positions[early], run.constraint_forces[early])
        expected = tensions(scene, positions, forces)
        row["tension error (N)"] = float(np.abs(measured - expected)[1:].max())
    else:
        row["tension error (N)"] = "n/a"
    row["cost (s/s)"] = run.info.wall_time / float(run.t[-1])
    return row


def table(title: str, cases: tuple[Case, ...], settings: tuple[Setting, ...], columns: tuple[str, ...]) -> None:
    print(f"\n## {title}\n")
    for case in cases:
        reference = solve(catalog.build(case.scene, case.parameters))
        print(f"### {case.label}\n")
        print("| setting | status | " + " | ".join(columns) + " |")
        print("|---|---|" + "---|" * len(columns))
        for setting in settings:
            row = measure(case, setting, reference)
            cells = [_cell(row.get(c, "")) for c in columns]
            print(f"| {setting.label} | {row['status']} | " + " | ".join(cells) + " |", flush=True)
        print()


def _cell(value: Any) -> str:
    return f"{value:.2g}" if isinstance(value, float) else str(value)


SLOW: set[str] = set()
#: The rows docs/engines.md quotes, measured by figures(): (case, setting) -> short key.
_QUOTED_CASES = {"bead60": BEAD_60, "double": DOUBLE}


def _k(text: str) -> str:
    return text.split(" (")[0].replace(", ", "_").replace(" ", "_")


def figures(quick: bool = False) -> dict[str, float]:
    """Every quoted cell: ``<case>|<setting>|<column>`` (case bead60 or double; setting as shortened by _k)."""
    f: dict[str, float] = {}
    for tag, case in _QUOTED_CASES.items():
        reference = solve(catalog.build(case.scene, case.parameters))
        for setting in KEPT_DEFAULTS[:3] + KEPT_DEFAULTS[4:6] + SOLVER_SETTINGS + (INERTIA_SETTINGS if tag == "bead60" else ()):
            row = measure(case, setting, reference)
            for column, value in row.items():
                if isinstance(value, float):
                    f[f"{tag}|{_k(setting.label)}|{column.split(' (')[0]}"] = value
    f["bead60|erp_gain_0.8"] = f["bead60|dantzig_ERP_0.2|constraint error"] / f["bead60|dantzig_ERP_0.8|constraint error"]
    f["bead10|p2p|period"] = _period_error("p2p")
    f["bead60|damping_lost_fraction"] = f["bead60|multibody_default_damping|energy drift"] / 0.5  # E* = m g L; swing energy 0.5 E*
    return f


def _period_error(variant: str, dt: float = 1e-3) -> float:
    """(T − T_exact)/T_exact of the 10° bead over three periods, from the zero crossings of x."""
    import math

    from engines.reference.closed_form import pendulum_period

    exact = pendulum_period(1.0, 9.81, math.radians(10.0))
    scene = catalog.build("bead", {"theta0": 10.0, "duration": 6.5})
    run = ENGINE.simulate(scene, dt, variant=variant, sample_interval=dt)
    x = run.positions[:, 0, 0]
    i = np.nonzero(np.signbit(x[1:]) != np.signbit(x[:-1]))[0]
    crossings = run.t[i] - x[i] * dt / (x[i + 1] - x[i])
    return float((2 * np.polyfit(np.arange(len(crossings)), crossings, 1)[0] - exact) / exact)


D = "docs/engines.md"
SOFT = "### What stays soft: solver, iterations, ERP (p2p)"


def _row(label: str, setting: str) -> Row:
    bead = (f"bead60|{setting}|constraint error", f"bead60|{setting}|energy drift")
    double = (f"double|{setting}|constraint error", f"double|{setting}|energy drift", f"double|{setting}|tension error")
    if setting == "multibody":
        bead, double = (None, bead[1]), (None, double[1], None)
    return Row(D, label, (bead, double, None), SOFT)


ROWS = [
    _row("si, 50 iterations, ERP 0.2 (defaults)", "si_50_iterations_ERP_0.2"),
    _row("si, 500 iterations", "si_500_iterations"),
    _row("pgs (MLCP), 50 iterations", "pgs"),
    _row("dantzig, ERP 0.2", "dantzig_ERP_0.2"),
    _row("dantzig, ERP 0", "dantzig_ERP_0"),
    _row("dantzig, ERP 0.8", "dantzig_ERP_0.8"),
    _row("multibody (no constraint)", "multibody"),
]
QUOTES = load_quotes(__file__)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="only the bead cases (a few seconds)")
    args = parser.parse_args(argv)
    print(f"# PyBullet {ENGINE.version()}: what each default costs")
    table(
        "Overrides switched off one at a time",
        (BEAD_60, BEAD_10) if args.quick else (BEAD_60, BEAD_10, DOUBLE),
        KEPT_DEFAULTS,
        ("energy drift", "swing (m)", "position error (m)", "constraint error (m)"),
    )
    table(
        "p2p: constraint solver, iterations, ERP",
        (BEAD_60,) if args.quick else (BEAD_60, DOUBLE, CHAIN, SPHERICAL),
        SOLVER_SETTINGS,
        ("constraint error (m)", "energy drift", "position error (m)", "tension error (N)", "cost (s/s)"),
    )
    table(
        "p2p: the point mass's central inertia (inertia_ratio · m · L²)",
        (BEAD_60,),
        INERTIA_SETTINGS,
        ("constraint error (m)", "energy drift", "position error (m)", "tension error (N)"),
    )
    if not args.quick:
        report(figures(), QUOTES, ROWS)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
