"""MuJoCo and pymunk with an injectable slowdown, for scripts/timing_gate_noise.py (not a real engine).

``XVAL_SLOWDOWN = k`` (an integer, default 1) makes each run do its whole
stepping k times over and report the sum of the loops' times: a build that
became k× slower, while the case (scene, variant, options, version) stays the
same, so the gate compares it with the baseline as the same case.
"""

from __future__ import annotations

import os
from dataclasses import replace

from engines.mujoco.adapter import MuJoCoEngine
from engines.pymunk.adapter import PymunkEngine


def _slowed(cls):
    class Slowed(cls):
        def _run(self, scene, schedule, settings):
            k = int(os.environ.get("XVAL_SLOWDOWN", "1"))
            runs = [super(Slowed, self)._run(scene, schedule, settings) for _ in range(k)]
            return replace(runs[-1], wall_time=sum(r.wall_time for r in runs))

    Slowed.__name__ = f"Slowed{cls.__name__}"
    return Slowed()


MUJOCO = _slowed(MuJoCoEngine)
PYMUNK = _slowed(PymunkEngine)
