"""Why mujoco/connect loses energy at its defaults, and why pybullet/p2p runs `ok` far from the reference.

Run:  .venv/bin/python scripts/soft_constraints.py      (about 10 s)

Energies are (E(t_end) − E(0)) / E* (negative: lost), E* = m g L; errors in units of L.
Quoted in docs/engines.md.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from quoted import load_quotes, report  # noqa: E402

from compare.results.metrics import position_error  # noqa: E402
from engines.scene import catalog  # noqa: E402
from engines.mujoco.adapter import ENGINE as MUJOCO  # noqa: E402
from engines.pybullet.adapter import ENGINE as PYBULLET  # noqa: E402
from engines.reference.reference import solve  # noqa: E402
from engines.scene.trajectory import max_constraint_error, total_energy  # noqa: E402

SLOW: set[str] = set()


def _run(engine, scene, variant, dt, options=None):
    run = engine.simulate(scene, dt, variant=variant, options=options or {})
    e = total_energy(scene, run.positions, run.velocities)
    return run, float((e[-1] - e[0]) / scene.characteristic_energy)


QUOTES, ROWS = load_quotes(__file__), []  # what docs quote from this script


def figures(quick: bool = False) -> dict[str, float]:
    f: dict[str, float] = {}
    bead = catalog.build("bead", {"duration": 10.0})
    # mujoco/connect: the loss does not shrink with dt (a property of the model, not of the step).
    for variant, dt, key in (("connect", 1e-3, "connect_1e-3"), ("connect", 1e-4, "connect_1e-4"),
                             ("connect-rk4", 1e-2, "connect_rk4_1e-2"), ("connect-rk4", 1e-3, "connect_rk4_1e-3"),
                             ("connect-stiff", 1e-3, "connect_stiff_1e-3"), ("connect-stiff", 1e-4, "connect_stiff_1e-4")):
        f[f"bead_energy_{key}"] = -_run(MUJOCO, bead, variant, dt)[1]
    for options, key in (({"solref": "0.02,0.5"}, "dampratio_0.5"), ({"solref": "0.02,0.1"}, "dampratio_0.1"),
                         ({"solimp": "0.9999,0.9999,0.001"}, "solimp_0.9999")):
        f[f"bead_energy_connect_rk4_{key}"] = -_run(MUJOCO, bead, "connect-rk4", 1e-3, options)[1]
    # pybullet/p2p on the default double pendulum over 2 s (the default suite's case).
    double = catalog.build("double-pendulum", {"duration": 2.0})
    reference = solve(double)
    length = double.characteristic_length
    for dt, key in ((10**-2.5, "3.16e-3"), (1e-3, "1e-3"), (1e-4, "1e-4")):
        run, energy = _run(PYBULLET, double, "p2p", dt)
        e = position_error(run.positions, reference.at(run.t)[0])
        f[f"p2p_double_status_ok_{key}"] = float(run.info.status == "ok")
        f[f"p2p_double_final_error_{key}"] = float(e[-1]) / length
        f[f"p2p_double_energy_{key}"] = -energy
        f[f"p2p_double_stretch_{key}"] = float(max_constraint_error(double, run.positions).max()) / length
    run, energy = _run(PYBULLET, double, "p2p-dantzig", 10**-2.5)
    f["p2p_dantzig_double_energy_3.16e-3"] = -energy
    f["p2p_dantzig_double_final_error_3.16e-3"] = float(
        position_error(run.positions, reference.at(run.t)[0])[-1]) / length
    return f



def main() -> None:
    report(figures(), QUOTES, ROWS)


if __name__ == "__main__":
    main()
