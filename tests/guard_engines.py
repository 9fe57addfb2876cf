"""Engines that exhaust a resource on purpose, for the guard-rail and fault tests (test-only; not collected).

Loaded by suites as ``guard_engines:HOG/<variant>``. ``memory`` allocates
``gib`` GiB at once (a case past ``--memory-limit``); ``children`` starts two
``sleep`` processes and then sleeps itself (a timed-out case whose engine
leaves children); ``slow`` is the reference itself, after ``seconds`` of
sleep. Every run that returns returns the reference solution.
"""

from __future__ import annotations

import subprocess
import time
from typing import Any, Mapping

import numpy as np

from engines.adapter import Engine, Option, RawRun, Schedule
from engines.scene import Scene

MODES = ("memory", "children", "slow")


class HogEngine(Engine):
    name = "hog"
    capabilities = frozenset({"3d", "constraint-forces"})
    options = {
        "mode": Option("mode", "memory", "which resource to exhaust", kind="str", choices=MODES),
        "gib": Option("gib", 3.0, "GiB to allocate (memory)"),
        "seconds": Option("seconds", 3600.0, "seconds to sleep first (slow)"),
    }
    variants = {mode: {"mode": mode} for mode in MODES}

    def version(self) -> str:
        return "test 1"

    def _run(self, scene: Scene, schedule: Schedule, settings: Mapping[str, Any]) -> RawRun:
        from engines.reference import solve

        mode = settings["mode"]
        if mode == "memory" and schedule.n_steps > 2:  # not in the two-step warm-up
            block = np.ones(int(settings["gib"] * 2**30) // 8)
            block[-1] = 0.0
        if mode == "children" and schedule.n_steps > 2:
            for _ in range(2):
                subprocess.Popen(["sleep", "3600"])
            time.sleep(3600)
        if mode == "slow" and schedule.n_steps > 2:
            time.sleep(settings["seconds"])
        positions, velocities, forces = solve(scene).at(schedule.times)
        return RawRun(positions, velocities, forces, steps=schedule.n_steps, wall_time=1e-3)


HOG = HogEngine()
