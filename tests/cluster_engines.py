"""A test engine that kills the Dask worker running it (test-only; not collected by pytest).

Loaded by suites as ``cluster_engines:WORKER_KILLER/<variant>``. The engine
runs in a case host, a child forked from the worker (compare.isolation), so
its parent process is the Dask worker: ``kill-worker`` SIGKILLs that parent,
as an out-of-memory killer or a lost machine would. ``exact`` returns the
reference solution.
"""

from __future__ import annotations

import os
import signal
from typing import Any, Mapping

from engines.adapter import Engine, Option, RawRun, Schedule
from engines.scene import Scene

MODES = ("exact", "kill-worker")


class WorkerKillerEngine(Engine):
    """exact: the reference; kill-worker: SIGKILLs the process that forked the case host (the Dask worker)."""

    name = "worker-killer"
    capabilities = frozenset({"3d", "constraint-forces"})
    options = {"mode": Option("mode", "exact", "what to do", kind="str", choices=MODES)}
    variants = {mode: {"mode": mode} for mode in MODES}

    def version(self) -> str:
        return "test 1"

    def _run(self, scene: Scene, schedule: Schedule, settings: Mapping[str, Any]) -> RawRun:
        from engines.reference import solve

        if settings["mode"] == "kill-worker":
            os.kill(os.getppid(), signal.SIGKILL)
            os._exit(9)  # no answer, and no orphaned case host left behind
        positions, velocities, forces = solve(scene).at(schedule.times)
        return RawRun(positions, velocities, forces, steps=schedule.n_steps, wall_time=1e-3)


WORKER_KILLER = WorkerKillerEngine()
