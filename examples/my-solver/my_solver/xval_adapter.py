"""The xval adapter of my-solver: translate a Scene, step the solver, record samples.

Registered in pyproject.toml under the entry point group ``xval.engines`` as
``my-solver``; suites name its variants ``my-solver/rattle`` and
``my-solver/shake``. xval checks what ``_run`` returns (shapes, units, the
initial state, finiteness), so this file only translates and steps.

Making it worse on purpose (the tutorial's failing gate): the environment
variable ``MY_SOLVER_NO_VELOCITY_PROJECTION=1`` switches the velocity
projection off in every variant, without changing the suite's engine ids or
options, so a gate compares the same cases and finds them worse.
"""

from __future__ import annotations

import os
from typing import Any, Mapping

from engines.external.plugin import Engine, Option, Recorder, Schedule, capabilities, scene_arrays
from engines.scene.scene import Scene

from my_solver import __version__
from my_solver.rattle import Constraints, Rattle

#: Set to 1 to disable the velocity projection (a deliberate regression, for the tutorial).
WORSEN_ENV = "MY_SOLVER_NO_VELOCITY_PROJECTION"


class MySolverEngine(Engine):
    """RATTLE (velocity Verlet + SHAKE + velocity projection) on point masses, in 3-D."""

    api_version = 1  # the xval engine protocol this adapter follows (docs/plugins.md)
    name = "my-solver"
    capabilities = capabilities(three_d=True, constraint_forces=True)
    options = {
        "project_velocities": Option("project_velocities", True,
                                     "project velocities onto the constraints after each step (RATTLE)", "bool"),
        "tolerance": Option("tolerance", 1e-12, "relative residual at which each projection stops"),
        "max_iterations": Option("max_iterations", 200, "Gauss-Seidel sweeps per projection", "int"),
    }
    variants = {"rattle": {}, "shake": {"project_velocities": False}}
    variant_docs = {
        "rattle": "velocity Verlet, SHAKE positions, projected velocities: order 2, symplectic",
        "shake": "velocity Verlet, SHAKE positions only: velocities keep an O(h) component along rods",
    }

    def version(self) -> str:
        return __version__

    def _run(self, scene: Scene, schedule: Schedule, settings: Mapping[str, Any]) -> Any:
        arrays = scene_arrays(scene)
        project = settings["project_velocities"] and os.environ.get(WORSEN_ENV, "") in ("", "0")
        solver = Rattle(
            arrays.masses,
            Constraints(arrays.first, arrays.second, arrays.anchors, arrays.lengths),
            arrays.gravity,
            tolerance=settings["tolerance"],
            max_iterations=settings["max_iterations"],
            project_velocities=project,
        )
        q, v = arrays.positions.copy(), arrays.velocities.copy()
        recorder = Recorder(scene, schedule, forces=True)
        # RATTLE's forces come out of a step; the t = 0 sample gets the exact ones of the initial state.
        recorder.record(0, q, v, solver.forces_at(q, v) if len(arrays.lengths) else None)
        with recorder.stepping():
            for step in range(1, schedule.n_steps + 1):
                q, v, forces = solver.step(q, v, schedule.dt)
                if recorder.wants(step):
                    with recorder.paused():
                        recorder.record(step, q, v, forces)
        return recorder.raw_run(settings={"my-solver.velocity_projection": project,
                                          "my-solver.worst_residual": solver.worst_residual})


ENGINE = MySolverEngine()
