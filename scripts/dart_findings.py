"""DART's two variants on the catalog scenes against the reference and MuJoCo (docs/engines.md, "DART").

Run:  .venv/bin/python scripts/dart_findings.py      (about ten seconds)

Per variant: the double pendulum's largest position error (m) over 2 s at dt = 1e-3 against the
reference, its energy drift max |E − E0| / E*, the observed order on the bead (θ0 = 60°, 1 s; world
at dt 5e-3..1.25e-3, rk4 at 4e-2..1e-2), and the largest distance to MuJoCo's scheme of the same
order (world against mujoco/hinge with both at inertia ratio 1e-9, rk4 against mujoco/hinge-rk4 at
MuJoCo's 1e-12). Then the spherical pendulum (ball joint, world) and the slider pendulum
(prismatic joint): position error and the drift of the conserved momentum.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from quoted import Quote, Row, report  # noqa: E402

from engines.scene import catalog  # noqa: E402
from engines.dart.adapter import ENGINE as DART  # noqa: E402
from engines.mujoco.adapter import ENGINE as MUJOCO  # noqa: E402
from engines.reference.reference import ENGINE as REFERENCE  # noqa: E402

G = 9.81
ORDER_STEPS = {"world": (5e-3, 2.5e-3, 1.25e-3), "rk4": (4e-2, 2e-2, 1e-2)}
MUJOCO_PEER = {"world": ("hinge", {"inertia_ratio": 1e-9}, {"inertia_ratio": 1e-9}),
               "rk4": ("hinge-rk4", {}, {"inertia_ratio": 1e-12})}


def _error(run, reference) -> float:
    return float(np.abs(run.positions - reference.positions).max())


def _drift(scene, run) -> float:
    m = scene.masses
    e = 0.5 * (m * (run.velocities**2).sum(-1)).sum(1) + (m * G * run.positions[..., 2]).sum(1)
    return float(np.abs(e - e[0]).max() / scene.characteristic_energy)


def figures(quick: bool = False) -> dict[str, float]:
    f: dict[str, float] = {}
    double = catalog.build("double-pendulum", {"duration": 2})
    reference = REFERENCE.simulate(double, 1e-3)
    bead = catalog.build("bead", {"theta0": 60, "duration": 1})
    for variant in ("world", "rk4"):
        run = DART.simulate(double, 1e-3, variant=variant)
        f[f"{variant}|error"] = _error(run, reference)
        f[f"{variant}|drift"] = _drift(double, run)
        steps = ORDER_STEPS[variant]
        errors = [_error(DART.simulate(bead, dt, variant=variant), REFERENCE.simulate(bead, dt)) for dt in steps]
        f[f"{variant}|order"] = float(np.polyfit(np.log(steps), np.log(errors), 1)[0])
        peer, peer_options, own_options = MUJOCO_PEER[variant]
        mine = DART.simulate(double, 1e-3, variant=variant, options=own_options)
        f[f"{variant}|mujoco"] = _error(mine, MUJOCO.simulate(double, 1e-3, variant=peer, options=peer_options))
    sphere = catalog.build("spherical-pendulum", {"duration": 2})
    run = DART.simulate(sphere, 1e-3)
    f["spherical|error"] = _error(run, REFERENCE.simulate(sphere, 1e-3))
    lz = np.cross(run.positions[:, 0], run.velocities[:, 0])[:, 2]
    f["spherical|lz"] = float(np.abs(lz - lz[0]).max())
    slider = catalog.build("slider-pendulum", {"duration": 2})
    for variant in ("world", "rk4"):
        run = DART.simulate(slider, 1e-3, variant=variant)
        px = (slider.masses * run.velocities[..., 0]).sum(1)
        f[f"slider-{variant}|momentum"] = float(np.abs(px - px[0]).max())
        f[f"slider-{variant}|error"] = _error(run, REFERENCE.simulate(slider, 1e-3))
    return f


D = "docs/engines.md"
HEADING = "## DART"
ROWS = [Row(D, f"`dart/{v}`", (f"{v}|error", f"{v}|drift", f"{v}|order"), HEADING) for v in ("world", "rk4")]
QUOTES = [
    Quote(D, "1.3e-3", "spherical|error", "ball joint: {} m"),
    Quote(D, "1.7e-3", "slider-world|momentum", "horizontal momentum by {} kg·m/s"),
]
SLOW: set[str] = set()


def main() -> None:
    f = figures()
    print("| variant | double pendulum error, dt = 1e-3 (m) | energy drift (E*) | observed order (bead) | "
          "distance to MuJoCo's same scheme (m) |")
    print("|---|---|---|---|---|")
    for v in ("world", "rk4"):
        print(f"| `dart/{v}` | {f[f'{v}|error']:.2g} | {f[f'{v}|drift']:.2g} | {f[f'{v}|order']:.2f} | "
              f"{f[f'{v}|mujoco']:.2g} |")
    report(f, QUOTES, ROWS)


if __name__ == "__main__":
    main()
