"""The point-mass inertia each rigid-body engine needs, and the error floor it sets (docs/engines.md).

Run:  .venv/bin/python scripts/inertia_floor.py      (a few seconds)

MuJoCo and PyBullet need a rotational inertia on every body; a point mass gets
``inertia_ratio · m · L²``. On a hinge (reduced coordinates) it adds to the link's
moment, so it is a model error of its own: the floor hinge-rk4 converges to. This
script measures that floor, how small a ratio each engine stays well-conditioned
with, and what PyBullet's former default (1e-4) cost the multibody variant.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from quoted import load_quotes, report  # noqa: E402

from compare.results.metrics import position_error  # noqa: E402
from engines.scene import catalog  # noqa: E402
from engines.mujoco.adapter import ENGINE as MUJOCO  # noqa: E402
from engines.pybullet.adapter import ENGINE as PYBULLET  # noqa: E402
from engines.reference.reference import solve  # noqa: E402

SLOW: set[str] = set()
MILD = {"theta1": 30.0, "theta2": 20.0, "duration": 2.0}


def _error(engine, scene, reference, variant, dt, ratio=None):
    options = {} if ratio is None else {"inertia_ratio": ratio}
    run = engine.simulate(scene, dt, variant=variant, options=options)
    return float(position_error(run.positions, reference.at(run.t)[0]).max()), run


#: The ensemble's initial angles: the default moved by each of these many ulps.
SPREAD = range(-3, 4)


def _ulps_apart(parameters, name: str) -> list[float]:
    """Parameter ``name``'s default moved by each of SPREAD ulps."""
    default = next(p.default for p in parameters if p.name == name)
    return [catalog.moved_by_ulps(default, k) for k in SPREAD]


QUOTES, ROWS = load_quotes(__file__), []  # what docs quote from this script


def figures(quick: bool = False) -> dict[str, float]:
    f: dict[str, float] = {}
    # MuJoCo hinge-rk4 at dt = 1e-4 over 2 s: its error is the inertia's (RK4's own is ~1e-14).
    for name, params in (("bead", {"duration": 2.0}), ("double-pendulum", {"duration": 2.0})):
        scene = catalog.build(name, params)
        reference = solve(scene)
        key = name.split("-")[0]
        for ratio, tag in ((1e-9, "1e-9"), (1e-12, "1e-12")):
            f[f"hinge_rk4_{key}_floor_{tag}"] = _error(MUJOCO, scene, reference, "hinge-rk4", 1e-4, ratio)[0]
        f[f"hinge_rk4_{key}_floor_per_ratio"] = f[f"hinge_rk4_{key}_floor_1e-9"] / 1e-9
    # PyBullet's spherical joint: its departure from MuJoCo's ball joint as the ratio shrinks. Round-off
    # amplified by 1/ratio sets it, so it is an ensemble's: the median and range over initial angles
    # SPREAD ulps apart (each member the same physics; docs quote the median with its range).
    for ratio, tag in ((1e-9, "1e-9"), (1e-10, "1e-10"), (1e-12, "1e-12")):
        members = []
        for theta0 in _ulps_apart(catalog.builder("spherical-pendulum").parameters, "theta0"):
            sphere = catalog.build("spherical-pendulum", {"duration": 2.0, "theta0": theta0})
            a = PYBULLET.simulate(sphere, 1e-3, variant="multibody", options={"inertia_ratio": ratio})
            b = MUJOCO.simulate(sphere, 1e-3, variant="hinge", options={"inertia_ratio": ratio})
            members.append(float(position_error(a.positions, b.positions).max()))
        key = f"spherical_pybullet_vs_mujoco_{tag}"
        f[key], f[f"{key}_low"], f[f"{key}_high"] = float(np.median(members)), min(members), max(members)
    # The mild double pendulum: observed order over dt = 1, 0.5, 0.25 ms, old and new ratio.
    scene = catalog.build("double-pendulum", MILD)
    reference = solve(scene)
    dts = np.array([1e-3, 5e-4, 2.5e-4])
    for ratio, tag in ((1e-4, "1e-4"), (1e-9, "1e-9")):
        errors = [_error(PYBULLET, scene, reference, "multibody", dt, ratio)[0] for dt in dts]
        f[f"mild_multibody_order_{tag}"] = float(np.polyfit(np.log(dts), np.log(errors), 1)[0])
        f[f"mild_multibody_error_{tag}"] = errors[0]
    f["mild_hinge_error"] = _error(MUJOCO, scene, reference, "hinge", 1e-3)[0]
    return f



def main() -> None:
    report(figures(), QUOTES, ROWS)


if __name__ == "__main__":
    main()
