"""Engines that misbehave on purpose, for the runner's isolation tests (test-only; not collected by pytest).

Loaded by suites as ``compare_engines:MISBEHAVING/<variant>``. Every variant
but the misbehaving ones returns the reference solution itself, so a case
that behaves has zero position error.

The engine runs in a case host, a child forked from the executor's worker
(compare.run.isolation), so its parent process is that worker: ``kill-worker``
SIGKILLs it, as an out-of-memory killer or a lost machine would (a pool
worker locally, a Dask worker on a cluster).
"""

from __future__ import annotations

import os
import signal
import time
from typing import Any, Mapping

import numpy as np

from engines.adapter import Engine, Option, RawRun, Schedule
from engines.scene import Scene

MODES = ("exact", "raise", "nan", "sleep", "kill", "exit", "drift", "kill-worker")


class MisbehavingEngine(Engine):
    """exact: the reference; raise: raises in the stepping loop; nan: NaN from halfway;
    sleep: sleeps for an hour; kill: SIGKILLs its own process; exit: os._exit(3);
    drift: the reference with the bead pushed 0.5 m off its wire (finite, but past the bounds);
    kill-worker: SIGKILLs the process that forked the case host (the executor's worker)."""

    name = "misbehaving"
    capabilities = frozenset({"3d", "constraint-forces"})
    options = {"mode": Option("mode", "exact", "how to misbehave", kind="str", choices=MODES)}
    variants = {mode: {"mode": mode} for mode in MODES}

    def version(self) -> str:
        return "test 1"

    def _run(self, scene: Scene, schedule: Schedule, settings: Mapping[str, Any]) -> RawRun:
        from engines.reference import solve

        mode = settings["mode"]
        if mode == "raise":
            raise RuntimeError("deliberate failure in the stepping loop")
        if mode == "sleep":
            time.sleep(3600)
        if mode == "kill":
            os.kill(os.getpid(), signal.SIGKILL)
        if mode == "exit":
            os._exit(3)
        if mode == "kill-worker":
            os.kill(os.getppid(), signal.SIGKILL)
            os._exit(9)  # no answer, and no orphaned case host left behind
        positions, velocities, forces = solve(scene).at(schedule.times)
        if mode == "nan":
            positions[len(positions) // 2 :] = np.nan
        if mode == "drift":
            # From the first step on: sample 0 must stay the initial state (engines.adapter.check_raw_run).
            positions[1:] = positions[1:] * 1.5
        return RawRun(positions, velocities, forces, steps=schedule.n_steps, wall_time=1e-3)


MISBEHAVING = MisbehavingEngine()
