"""Engines that exhaust a resource on purpose, for the guard-rail and fault tests (test-only; not collected).

Loaded by suites as ``guard_engines:HOG/<variant>``. ``memory`` allocates
``gib`` GiB at once (a case past ``--memory-limit``); ``children`` starts two
``sleep`` processes and then sleeps itself (a timed-out case whose engine
leaves children); ``slow`` is the reference itself, after ``seconds`` of
sleep; ``spin`` spends minutes in one compiled numba loop (no Python runs,
so no Python signal handler either). Every run that returns returns the
reference solution.
"""

from __future__ import annotations

import subprocess
import time
from typing import Any, Mapping

import numpy as np

from engines.adapter import Engine, Option, RawRun, Schedule
from engines.scene.scene import Scene

MODES = ("memory", "children", "slow", "spin")


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
        from engines.reference.reference import solve

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
        if mode == "spin" and schedule.n_steps > 2:
            _spin(10**12)  # ~10 min and more of one core
        positions, velocities, forces = solve(scene).at(schedule.times)
        return RawRun(positions, velocities, forces, steps=schedule.n_steps, wall_time=1e-3)


def _spin(n: int) -> float:
    """n iterations of a compiled loop that holds the GIL throughout (numba, compiled on first call)."""
    import numba

    @numba.njit(cache=False)
    def loop(n):
        x = 0.0
        for k in range(n):
            x = x * 0.5 + k
        return x

    return loop(n)


HOG = HogEngine()
